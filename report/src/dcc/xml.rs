//! The DCC's XML writer: elements, text (refused where XML 1.0 cannot
//! hold it or a certificate cannot print it, escaped by quick-xml
//! otherwise), D-SI quantities and lists, statements, contacts and
//! equipment, as [`super`] writes them.

use super::{DEGREE, K, NOT_STATED, PROBABILITY};
use crate::certificate::identifications;
use anyhow::Context as _;
use quick_xml::Writer;
use quick_xml::events::{BytesEnd, BytesStart, BytesText, Event};
use survey_store::config::{Address, Equipment};

/// The XML being written.
pub(super) struct Xml {
    pub(super) w: Writer<Vec<u8>>,
    /// The distribution of the expanded uncertainties being written: the
    /// measured figures' ([`NORMAL`]) or the table's ([`TABLE_DISTRIBUTION`]).
    pub(super) distribution: &'static str,
}

pub(super) type Attrs<'a> = &'a [(&'a str, &'a str)];

impl Xml {
    pub(super) fn open(&mut self, name: &str, attrs: Attrs<'_>) -> anyhow::Result<()> {
        let start = BytesStart::new(name).with_attributes(attrs.iter().copied());
        self.w.write_event(Event::Start(start)).context("writing the DCC")?;
        Ok(())
    }

    pub(super) fn close(&mut self, name: &str) -> anyhow::Result<()> {
        self.w.write_event(Event::End(BytesEnd::new(name))).context("writing the DCC")?;
        Ok(())
    }

    /// `<name>text</name>`.
    pub(super) fn leaf(&mut self, name: &str, text: &str) -> anyhow::Result<()> {
        xml_text(name, text)?;
        self.open(name, &[])?;
        self.w.write_event(Event::Text(BytesText::new(text))).context("writing the DCC")?;
        self.close(name)
    }

    /// A `textType`/`richContentType` element: `<name><dcc:content lang="en">text</dcc:content></name>`.
    pub(super) fn words(&mut self, name: &str, text: &str) -> anyhow::Result<()> {
        xml_text(name, text)?;
        self.open(name, &[])?;
        self.open("dcc:content", &[("lang", "en")])?;
        self.w.write_event(Event::Text(BytesText::new(text))).context("writing the DCC")?;
        self.close("dcc:content")?;
        self.close(name)
    }

    /// A quantity: name, one `si:real` in degrees, its expanded uncertainty when known.
    pub(super) fn angle(&mut self, ref_type: &str, name: &str, value: &str, u: Option<&str>) -> anyhow::Result<()> {
        // PTB's own refType beside ours (refType is a list): a consumer finds the measured values by it.
        let ref_type = match ref_type {
            r if r.starts_with("survey_") => format!("basic_measuredValue {r}"),
            r => r.to_string(),
        };
        self.open("dcc:quantity", &[("refType", ref_type.as_str())])?;
        self.words("dcc:name", name)?;
        self.open("si:real", &[])?;
        self.leaf("si:value", value)?;
        self.leaf("si:unit", DEGREE)?;
        if let Some(u) = u {
            self.open("si:expandedUnc", &[])?;
            self.leaf("si:uncertainty", u)?;
            self.leaf("si:coverageFactor", K)?;
            self.leaf("si:coverageProbability", PROBABILITY)?;
            self.leaf("si:distribution", self.distribution)?;
            self.close("si:expandedUnc")?;
        }
        self.close("si:real")?;
        self.close("dcc:quantity")
    }

    /// A list quantity (`si:realListXMLList`) in `unit`, with one expanded uncertainty for every value.
    pub(super) fn list(
        &mut self,
        ref_type: &str,
        name: &str,
        values: &[String],
        unit: &str,
        u: Option<&str>,
    ) -> anyhow::Result<()> {
        self.open("dcc:quantity", &[("refType", ref_type)])?;
        self.words("dcc:name", name)?;
        self.open("si:realListXMLList", &[])?;
        self.leaf("si:valueXMLList", &values.join(" "))?;
        self.leaf("si:unitXMLList", unit)?;
        if let Some(u) = u {
            self.open("si:expandedUncXMLList", &[])?;
            self.leaf("si:uncertaintyXMLList", u)?;
            self.leaf("si:coverageFactorXMLList", K)?;
            self.leaf("si:coverageProbabilityXMLList", PROBABILITY)?;
            self.leaf("si:distributionXMLList", self.distribution)?;
            self.close("si:expandedUncXMLList")?;
        }
        self.close("si:realListXMLList")?;
        self.close("dcc:quantity")
    }

    /// A statement: its declaration, and the norm and clause it answers.
    pub(super) fn statement(
        &mut self,
        ref_type: &str,
        norm: Option<(&str, &str)>,
        declaration: &str,
    ) -> anyhow::Result<()> {
        self.open("dcc:statement", &[("refType", ref_type)])?;
        if let Some((norm, clause)) = norm {
            self.leaf("dcc:norm", norm)?;
            self.leaf("dcc:reference", clause)?;
        }
        self.words("dcc:declaration", declaration)?;
        self.close("dcc:statement")
    }

    /// A contact with a name and where it is: its postal address as the
    /// DCC structures one when it is stated, else the name as free text.
    pub(super) fn contact(
        &mut self,
        name: &str,
        who: &str,
        address: Option<&Address>,
        country: Option<&str>,
    ) -> anyhow::Result<()> {
        self.open(name, &[])?;
        self.words("dcc:name", who)?;
        self.open("dcc:location", &[])?;
        self.location(address)?;
        match country.or_else(|| address.and_then(|a| a.country.as_deref())) {
            Some(c) => self.leaf("dcc:countryCode", c)?,
            // The schema needs a part; the name is not repeated as its place.
            None if address.is_none() => self.words("dcc:further", "postal address not stated")?,
            None => {}
        }
        self.close("dcc:location")?;
        self.close(name)
    }

    /// A postal address's parts (but its country), each in its element.
    pub(super) fn location(&mut self, address: Option<&Address>) -> anyhow::Result<()> {
        let Some(a) = address else { return Ok(()) };
        let parts = [
            ("dcc:street", &a.street),
            ("dcc:streetNo", &a.street_no),
            ("dcc:postCode", &a.post_code),
            ("dcc:city", &a.city),
            ("dcc:state", &a.state),
        ];
        for (element, value) in parts {
            if let Some(v) = value.as_deref().filter(|v| !v.trim().is_empty()) {
                xml_text(element, v)?;
                self.leaf(element, v)?;
            }
        }
        Ok(())
    }

    /// An instrument's manufacturer (named, or "not stated": the item's is required), model and identifications.
    pub(super) fn equipment(
        &mut self,
        e: Option<&Equipment>,
        required: bool,
        more: &[(&str, &str, &str)],
    ) -> anyhow::Result<()> {
        match e.and_then(|e| e.manufacturer.as_deref()) {
            Some(m) => {
                self.open("dcc:manufacturer", &[])?;
                self.words("dcc:name", m)?;
                self.close("dcc:manufacturer")?;
            }
            None if required => {
                self.open("dcc:manufacturer", &[])?;
                self.words("dcc:name", NOT_STATED)?;
                self.close("dcc:manufacturer")?;
            }
            None => {}
        }
        if let Some(m) = e.and_then(|e| e.model.as_deref()) {
            xml_text("dcc:model", m)?;
            self.leaf("dcc:model", m)?;
        }
        let mut ids: Vec<(&str, &str, &str)> = e.map(identifications).unwrap_or_default();
        ids.extend_from_slice(more);
        if ids.is_empty() {
            return Ok(());
        }
        self.open("dcc:identifications", &[])?;
        for (issuer, value, name) in ids {
            self.open("dcc:identification", &[])?;
            self.leaf("dcc:issuer", issuer)?;
            xml_text("dcc:value", value)?;
            self.leaf("dcc:value", value)?;
            self.words("dcc:name", name)?;
            self.close("dcc:identification")?;
        }
        self.close("dcc:identifications")
    }
}

/// Refuse text that XML 1.0 cannot hold as written or that a certificate
/// cannot print: a control character but tab and line feed (NUL and most C0
/// controls are not XML characters; a carriage return would be read back as
/// a line feed), U+FFFE and U+FFFF. What XML can hold, quick-xml escapes
/// (`&`, `<`, `>`, quotes). The configuration and the flags refuse these
/// first; this is for what reaches the writer otherwise (a survey stored
/// before they did).
pub(super) fn xml_text(element: &str, text: &str) -> anyhow::Result<()> {
    let bad = |c: char| (c.is_control() && c != '\n' && c != '\t') || c == '\u{FFFE}' || c == '\u{FFFF}';
    match text.chars().enumerate().find(|(_, c)| bad(*c)) {
        None => Ok(()),
        Some((i, c)) => Err(survey_lab::error::bad_input(format!(
            "the DCC cannot hold {element}'s text {:?}: the character U+{:04X} at character {} is not printable \
             (state the field again with its survey report flag)",
            text.chars().take(40).collect::<String>(),
            c as u32,
            i + 1
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rounding::NORMAL;

    #[test]
    fn text_xml_cannot_hold_is_refused_and_the_rest_is_escaped() {
        for bad in ["J. Smith\u{7}", "a\u{0}b", "a\rb", "\u{1b}[31m", "a\u{85}", "\u{FFFF}"] {
            let e = xml_text("dcc:content", bad).unwrap_err();
            assert!(survey_lab::error::is_bad_input(&e), "{e:#}");
            assert!(format!("{e:#}").contains("U+"), "{e:#}");
        }
        let hostile = "<a b=\"c\">&amp; ]]> '\u{202E}x\ty\nz \u{1F600}";
        xml_text("dcc:content", hostile).unwrap();
        let mut x = Xml { w: Writer::new(Vec::new()), distribution: NORMAL };
        x.words("dcc:name", hostile).unwrap();
        let written = String::from_utf8(x.w.into_inner()).unwrap();
        let mut reader = quick_xml::Reader::from_str(&written);
        let mut text = String::new();
        loop {
            match reader.read_event().unwrap() {
                Event::Eof => break,
                Event::Text(t) => text += &t.xml10_content(),
                Event::GeneralRef(r) => {
                    text += &quick_xml::escape::unescape(&format!("&{};", r.xml10_content())).unwrap();
                }
                _ => {}
            }
        }
        assert_eq!(text, hostile, "read back as written: {written}");
    }
}
