//! Codec tests: the layouts of CiA 301, refusals, round trips, arbitrary frames.

use super::*;
use proptest::prelude::*;

#[test]
fn layouts_match_cia_301() {
    // Read the statusword: 40 41 60 00.
    assert_eq!(SdoRequest::InitiateUpload { index: 0x6041, subindex: 0 }.encode(), [0x40, 0x41, 0x60, 0, 0, 0, 0, 0]);
    // Expedited upload response of 2 bytes (n = 2): 4B.
    let r = SdoResponse::InitiateUpload {
        index: 0x6041,
        subindex: 0,
        data: InitData::Expedited { data: vec![0x37, 0x06], size_indicated: true },
    };
    assert_eq!(r.encode(), [0x4B, 0x41, 0x60, 0, 0x37, 0x06, 0, 0]);
    // Expedited download of 4 bytes (n = 0): 23; of 1 byte: 2F.
    let w = |data: Vec<u8>| SdoRequest::InitiateDownload {
        index: 0x607A,
        subindex: 0,
        data: InitData::Expedited { data, size_indicated: true },
    };
    assert_eq!(w(vec![1, 2, 3, 4]).encode()[0], 0x23);
    assert_eq!(w(vec![1]).encode()[0], 0x2F);
    assert_eq!(w(vec![1, 2]).encode()[0], 0x2B);
    // Segmented initiate with size: 21 / 41, size little-endian.
    let seg =
        SdoRequest::InitiateDownload { index: 0x2100, subindex: 0, data: InitData::Segmented { size: Some(300) } };
    assert_eq!(seg.encode(), [0x21, 0x00, 0x21, 0, 0x2C, 0x01, 0, 0]);
    // Download response 60, segment responses 20 / 30, upload segment requests 60 / 70.
    assert_eq!(SdoResponse::InitiateDownload { index: 0x6040, subindex: 0 }.encode()[0], 0x60);
    assert_eq!(SdoResponse::DownloadSegment { toggle: true }.encode()[0], 0x30);
    assert_eq!(SdoRequest::UploadSegment { toggle: false }.encode()[0], 0x60);
    assert_eq!(SdoRequest::UploadSegment { toggle: true }.encode()[0], 0x70);
    // A last upload segment with 3 bytes, toggle 1: 0 | 1<<4 | 4<<1 | 1 = 0x19.
    let s = SdoResponse::UploadSegment { toggle: true, data: vec![b'a', b'b', b'c'], last: true };
    assert_eq!(s.encode(), [0x19, b'a', b'b', b'c', 0, 0, 0, 0]);
    // Abort: 80, multiplexer, code little-endian.
    let a = SdoResponse::Abort { index: 0x607A, subindex: 0, code: abort::VALUE_RANGE };
    assert_eq!(a.encode(), [0x80, 0x7A, 0x60, 0, 0x30, 0x00, 0x09, 0x06]);
}

#[test]
fn decoding_refuses_what_it_must() {
    assert_eq!(SdoResponse::decode(&[0x43, 0, 0x10, 0]), Err(SdoDecodeError::Length(4)));
    assert_eq!(SdoResponse::decode(&[0xE0, 0, 0, 0, 0, 0, 0, 0]), Err(SdoDecodeError::Specifier(7)));
    assert_eq!(SdoRequest::decode(&[0xC0, 0, 0, 0, 0, 0, 0, 0]), Err(SdoDecodeError::BlockTransfer(6)));
    assert_eq!(SdoResponse::decode(&[0xA0, 0, 0, 0, 0, 0, 0, 0]), Err(SdoDecodeError::BlockTransfer(5)));
    // Expedited without size: all four bytes are data.
    assert_eq!(
        SdoResponse::decode(&[0x42, 0x00, 0x10, 0, 1, 2, 3, 4]),
        Ok(SdoResponse::InitiateUpload {
            index: 0x1000,
            subindex: 0,
            data: InitData::Expedited { data: vec![1, 2, 3, 4], size_indicated: false }
        })
    );
}

#[test]
fn abort_codes_have_texts_and_classes() {
    assert_eq!(abort_text(abort::NO_OBJECT), "Object does not exist in the object dictionary");
    assert_eq!(abort_text(abort::TIMEOUT), "SDO protocol timed out");
    assert_eq!(abort_text(0x1234_5678), "unknown abort code");
    assert_eq!(abort_kind(abort::VALUE_RANGE), ErrorKind::Usage);
    assert_eq!(abort_kind(abort::DEVICE_STATE), ErrorKind::Usage);
    assert_eq!(abort_kind(abort::NO_OBJECT), ErrorKind::Device);
    assert_eq!(abort_kind(abort::READ_ONLY), ErrorKind::Device);
    assert_eq!(Multiplexer(0x6041, 0).to_string(), "0x6041:00");
}

#[test]
fn reassembler_checks_toggle_size_and_end() {
    let mut r = Reassembler::new(Some(9), 100).unwrap();
    assert_eq!(r.push(true, &[1; 7], false), Err(SegmentError::Toggle { expected: false, got: true }));
    assert_eq!(r.push(false, &[1; 7], false), Ok(false));
    assert_eq!(r.push(true, &[1; 3], true), Err(SegmentError::Size { indicated: 9, received: 10 }));
    assert_eq!(r.push(true, &[1; 1], true), Err(SegmentError::Size { indicated: 9, received: 8 }));
    assert_eq!(r.push(true, &[1; 2], true), Ok(true));
    assert_eq!(r.push(false, &[], true), Err(SegmentError::AfterEnd));
    assert_eq!(r.into_data().len(), 9);
    assert_eq!(Reassembler::new(Some(101), 100).unwrap_err(), SegmentError::TooLong { max: 100 });
    let mut r = Reassembler::new(None, 10).unwrap();
    r.push(false, &[0; 7], false).unwrap();
    assert_eq!(r.push(true, &[0; 7], false).unwrap_err().abort_code(), abort::OUT_OF_MEMORY);
    assert_eq!(SegmentError::Toggle { expected: true, got: false }.abort_code(), abort::TOGGLE_BIT);
    assert_eq!(SegmentError::Size { indicated: 9, received: 10 }.abort_code(), abort::LENGTH_TOO_HIGH);
    assert_eq!(SegmentError::Size { indicated: 9, received: 8 }.abort_code(), abort::LENGTH_TOO_LOW);
    // Empty data: one empty last segment.
    let mut s = Segmenter::new(Vec::new());
    assert_eq!(s.next_segment(), Some(Segment { toggle: false, data: vec![], last: true }));
    assert_eq!(s.next_segment(), None);
}

fn init_data() -> impl Strategy<Value = InitData> {
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 1..=4)
            .prop_map(|data| InitData::Expedited { data, size_indicated: true }),
        proptest::collection::vec(any::<u8>(), 4..=4)
            .prop_map(|data| InitData::Expedited { data, size_indicated: false }),
        proptest::option::of(any::<u32>()).prop_map(|size| InitData::Segmented { size }),
    ]
}

fn request() -> impl Strategy<Value = SdoRequest> {
    prop_oneof![
        (any::<u16>(), any::<u8>(), init_data()).prop_map(|(index, subindex, data)| SdoRequest::InitiateDownload {
            index,
            subindex,
            data
        }),
        (any::<bool>(), proptest::collection::vec(any::<u8>(), 0..=7), any::<bool>())
            .prop_map(|(toggle, data, last)| SdoRequest::DownloadSegment { toggle, data, last }),
        (any::<u16>(), any::<u8>()).prop_map(|(index, subindex)| SdoRequest::InitiateUpload { index, subindex }),
        any::<bool>().prop_map(|toggle| SdoRequest::UploadSegment { toggle }),
        (any::<u16>(), any::<u8>(), any::<u32>()).prop_map(|(index, subindex, code)| SdoRequest::Abort {
            index,
            subindex,
            code
        }),
    ]
}

fn response() -> impl Strategy<Value = SdoResponse> {
    prop_oneof![
        (any::<u16>(), any::<u8>(), init_data()).prop_map(|(index, subindex, data)| SdoResponse::InitiateUpload {
            index,
            subindex,
            data
        }),
        (any::<bool>(), proptest::collection::vec(any::<u8>(), 0..=7), any::<bool>())
            .prop_map(|(toggle, data, last)| SdoResponse::UploadSegment { toggle, data, last }),
        (any::<u16>(), any::<u8>()).prop_map(|(index, subindex)| SdoResponse::InitiateDownload { index, subindex }),
        any::<bool>().prop_map(|toggle| SdoResponse::DownloadSegment { toggle }),
        (any::<u16>(), any::<u8>(), any::<u32>()).prop_map(|(index, subindex, code)| SdoResponse::Abort {
            index,
            subindex,
            code
        }),
    ]
}

proptest! {
    #[test]
    fn requests_round_trip(r in request()) {
        let bytes = r.encode();
        prop_assert_eq!(SdoRequest::decode(&bytes), Ok(r.clone()));
        // Re-encoding the decoded frame gives the same bytes.
        prop_assert_eq!(SdoRequest::decode(&bytes).unwrap().encode(), bytes);
    }

    #[test]
    fn responses_round_trip(r in response()) {
        let bytes = r.encode();
        prop_assert_eq!(SdoResponse::decode(&bytes), Ok(r.clone()));
        prop_assert_eq!(SdoResponse::decode(&bytes).unwrap().encode(), bytes);
    }

    #[test]
    fn arbitrary_frames_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..=8)) {
        // Whatever decodes, re-encodes to a frame that decodes to the same value.
        if let Ok(r) = SdoRequest::decode(&bytes) {
            prop_assert_eq!(SdoRequest::decode(&r.encode()), Ok(r));
        }
        if let Ok(r) = SdoResponse::decode(&bytes) {
            prop_assert_eq!(SdoResponse::decode(&r.encode()), Ok(r));
        }
        if bytes.len() != 8 {
            prop_assert!(SdoRequest::decode(&bytes).is_err() && SdoResponse::decode(&bytes).is_err());
        }
    }

    #[test]
    fn segments_rejoin_through_the_codec(data in proptest::collection::vec(any::<u8>(), 0..200), indicated in any::<bool>()) {
        let mut s = Segmenter::new(data.clone());
        let size = indicated.then_some(data.len() as u32);
        let mut r = Reassembler::new(size, 200).unwrap();
        let mut count = 0;
        while let Some(seg) = s.next_segment() {
            count += 1;
            // Through the frame codec, as on the wire.
            let frame = SdoResponse::UploadSegment { toggle: seg.toggle, data: seg.data.clone(), last: seg.last }.encode();
            let SdoResponse::UploadSegment { toggle, data: d, last } = SdoResponse::decode(&frame).unwrap() else {
                panic!("not a segment");
            };
            prop_assert_eq!(r.push(toggle, &d, last), Ok(last));
        }
        prop_assert_eq!(count, data.len().div_ceil(SEGMENT_BYTES).max(1));
        prop_assert!(s.is_done() && r.is_done());
        prop_assert_eq!(r.into_data(), data);
    }

    #[test]
    fn a_repeated_or_skipped_segment_is_a_toggle_error(data in proptest::collection::vec(any::<u8>(), 15..100), k in any::<prop::sample::Index>()) {
        let segs: Vec<Segment> = {
            let mut s = Segmenter::new(data);
            std::iter::from_fn(|| s.next_segment()).collect()
        };
        let k = k.index(segs.len() - 1);
        let mut r = Reassembler::new(None, 1000).unwrap();
        for seg in &segs[..=k] {
            r.push(seg.toggle, &seg.data, seg.last).unwrap();
        }
        // The same segment again (a duplicate frame) has the wrong toggle.
        let again = &segs[k];
        let is_toggle_error = matches!(r.push(again.toggle, &again.data, again.last), Err(SegmentError::Toggle { .. }));
        prop_assert!(is_toggle_error);
    }
}
