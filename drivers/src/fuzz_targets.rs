//! The codecs under arbitrary bytes: one function per wire codec, shared by
//! the cargo-fuzz harnesses (`fuzz/fuzz_targets/`, run on nightly) and the
//! bounded replay on stable (`positioner-drivers/tests/codec_fuzz.rs`, in CI, replays every codec of both crates).
//!
//! Each function feeds `data` to every decoder of its codec, whole and cut
//! into chunks at sizes drawn from the data itself, and checks what must hold
//! for any input: no panic (the harness catches one), every buffer bounded,
//! and whatever decodes encodes to bytes that decode to the same thing again
//! (a round trip on the decoded value, so NaN fields compare by their bytes).

use crate::elcomat;
use crate::emscon::packets::{Framer, Reply as EmsconReply, ReplyDecoder, Request as EmsconRequest, RequestDecoder};

/// The most bytes a partial line or packet may hold in any decoder here (the
/// largest is emScon's 64 KiB packet limit); checked after every push.
pub const MAX_BUFFERED: usize = 1 << 17;

/// `data` in chunks whose sizes (1 to 16) come from its first byte.
pub fn chunks(data: &[u8]) -> impl Iterator<Item = &[u8]> {
    let step = data.first().map_or(1, |b| usize::from(b % 16) + 1);
    data.chunks(step)
}

/// emScon TPI: the framer and both decoders over chunks (bounded buffers,
/// the framing lost only on an absurd size), every frame decoded as a request
/// and a reply, and what decodes encoded to bytes that decode to the same bytes.
pub fn emscon(data: &[u8]) {
    let mut framer = Framer::new();
    let mut replies = ReplyDecoder::new();
    let mut requests = RequestDecoder::new();
    for chunk in chunks(data) {
        framer.push(chunk);
        replies.push(chunk);
        requests.push(chunk);
        assert!(framer.buffered_len() <= MAX_BUFFERED && replies.buffered_len() <= MAX_BUFFERED);
        while let Some(frame) = framer.next_frame() {
            let Ok(frame) = frame else { continue };
            emscon_frame(&frame);
        }
        while replies.next_reply().is_some() {}
        while requests.next_request().is_some() {}
    }
    emscon_frame(data);
}

fn emscon_frame(frame: &[u8]) {
    if let Ok(r) = EmsconRequest::decode(frame) {
        let bytes = r.encode();
        let again = EmsconRequest::decode(&bytes).expect("an encoded request decodes");
        assert_eq!(again.encode(), bytes, "{frame:02x?}");
    }
    if let Ok(r) = EmsconReply::decode(frame) {
        let bytes = r.encode();
        let again = EmsconReply::decode(&bytes).expect("an encoded reply decodes");
        assert_eq!(again.encode(), bytes, "{frame:02x?}");
    }
    let _ = EmsconRequest::command_of(frame);
}

/// ELCOMAT: the reply and command decoders over chunks (bounded lines), every
/// line decoded both ways, a decoded reply encoded and decoded to itself.
pub fn elcomat(data: &[u8]) {
    let mut replies = elcomat::Decoder::new();
    let mut commands = elcomat::CommandDecoder::new();
    for chunk in chunks(data) {
        replies.push(chunk);
        commands.push(chunk);
        assert!(replies.buffered_len() <= MAX_BUFFERED);
        while let Some(r) = replies.next_reply() {
            if let Ok(r) = r {
                elcomat_reply(&r);
            }
        }
        while let Some(c) = commands.next_command() {
            if let Ok(c) = c {
                assert_eq!(elcomat::decode_command(elcomat::encode_command(c).trim_ascii_end()), Ok(c));
            }
        }
    }
    if let Ok(r) = elcomat::decode_reply(data) {
        elcomat_reply(&r);
    }
    let _ = elcomat::decode_command(data);
}

fn elcomat_reply(r: &elcomat::Reply) {
    let _ = (r.validity(), r.reading(), r.validity_text());
    let bytes = elcomat::encode_reply(r);
    let again = elcomat::decode_reply(bytes.trim_ascii_end()).expect("an encoded reply decodes");
    assert_eq!(elcomat::encode_reply(&again), bytes, "{r:?}");
}
