//! The history cache's bytes ([`super::cache`]): little-endian lengths and
//! numbers, every f64 by its bits (NaN, -0.0 and subnormals come back as
//! they went: a cached entry prints exactly what the computed one prints),
//! and a JSON value by its tree (its numbers as serde_json holds them:
//! unsigned, signed or f64 bits), never through JSON text, whose parser
//! need not give back every bit of a float.

use serde_json::{Map, Number, Value};

/// Bytes that are not an encoding of this version: the entry is not used
/// (it is computed again).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("a cache entry that does not decode")]
pub struct Malformed;

/// How deep a decoded JSON value may nest (the change document nests 3).
const MAX_DEPTH: usize = 32;

/// Bytes being written.
#[derive(Debug, Default)]
pub struct Writer(Vec<u8>);

impl Writer {
    /// The bytes written.
    pub fn into_bytes(self) -> Vec<u8> {
        self.0
    }

    pub fn u8(&mut self, v: u8) {
        self.0.push(v);
    }

    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }

    /// A flag, then the value when there is one.
    pub fn opt_f64(&mut self, v: Option<f64>) {
        match v {
            Some(v) => {
                self.u8(1);
                self.f64(v);
            }
            None => self.u8(0),
        }
    }

    pub fn str(&mut self, s: &str) {
        self.u64(s.len() as u64);
        self.0.extend_from_slice(s.as_bytes());
    }

    /// A JSON value, as its tree.
    pub fn value(&mut self, v: &Value) {
        match v {
            Value::Null => self.u8(0),
            Value::Bool(false) => self.u8(1),
            Value::Bool(true) => self.u8(2),
            Value::Number(n) => {
                if let Some(u) = n.as_u64() {
                    self.u8(3);
                    self.u64(u);
                } else if let Some(i) = n.as_i64() {
                    self.u8(4);
                    self.u64(i as u64);
                } else {
                    self.u8(5);
                    self.f64(n.as_f64().unwrap_or(f64::NAN));
                }
            }
            Value::String(s) => {
                self.u8(6);
                self.str(s);
            }
            Value::Array(a) => {
                self.u8(7);
                self.u64(a.len() as u64);
                for x in a {
                    self.value(x);
                }
            }
            Value::Object(m) => {
                self.u8(8);
                self.u64(m.len() as u64);
                for (k, x) in m {
                    self.str(k);
                    self.value(x);
                }
            }
        }
    }
}

/// Bytes being read.
#[derive(Debug)]
pub struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes }
    }

    /// Every byte was read.
    pub fn end(&self) -> Result<(), Malformed> {
        if self.bytes.is_empty() { Ok(()) } else { Err(Malformed) }
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], Malformed> {
        if n > self.bytes.len() {
            return Err(Malformed);
        }
        let (head, tail) = self.bytes.split_at(n);
        self.bytes = tail;
        Ok(head)
    }

    pub fn u8(&mut self) -> Result<u8, Malformed> {
        Ok(self.take(1)?[0])
    }

    pub fn u64(&mut self) -> Result<u64, Malformed> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes(b.try_into().map_err(|_| Malformed)?))
    }

    pub fn f64(&mut self) -> Result<f64, Malformed> {
        Ok(f64::from_bits(self.u64()?))
    }

    pub fn opt_f64(&mut self) -> Result<Option<f64>, Malformed> {
        match self.u8()? {
            0 => Ok(None),
            1 => Ok(Some(self.f64()?)),
            _ => Err(Malformed),
        }
    }

    /// A length, no longer than the bytes left (each item takes one at least).
    pub fn count(&mut self) -> Result<usize, Malformed> {
        let n = usize::try_from(self.u64()?).map_err(|_| Malformed)?;
        if n > self.bytes.len() { Err(Malformed) } else { Ok(n) }
    }

    pub fn str(&mut self) -> Result<String, Malformed> {
        let n = self.count()?;
        String::from_utf8(self.take(n)?.to_vec()).map_err(|_| Malformed)
    }

    pub fn value(&mut self) -> Result<Value, Malformed> {
        self.value_at(0)
    }

    fn value_at(&mut self, depth: usize) -> Result<Value, Malformed> {
        if depth > MAX_DEPTH {
            return Err(Malformed);
        }
        Ok(match self.u8()? {
            0 => Value::Null,
            1 => Value::Bool(false),
            2 => Value::Bool(true),
            3 => Value::Number(self.u64()?.into()),
            4 => Value::Number((self.u64()? as i64).into()),
            5 => Number::from_f64(self.f64()?).map_or(Value::Null, Value::Number),
            6 => Value::String(self.str()?),
            7 => {
                let n = self.count()?;
                let mut a = Vec::with_capacity(n);
                for _ in 0..n {
                    a.push(self.value_at(depth + 1)?);
                }
                Value::Array(a)
            }
            8 => {
                let n = self.count()?;
                let mut m = Map::new();
                for _ in 0..n {
                    let k = self.str()?;
                    m.insert(k, self.value_at(depth + 1)?);
                }
                Value::Object(m)
            }
            _ => return Err(Malformed),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use serde_json::json;

    fn round_trip(v: &Value) -> Value {
        let mut w = Writer::default();
        w.value(v);
        let bytes = w.into_bytes();
        let mut r = Reader::new(&bytes);
        let back = r.value().unwrap();
        r.end().unwrap();
        back
    }

    #[test]
    fn a_value_comes_back_as_it_went_every_number_as_serde_json_held_it() {
        let v = json!({
            "verdict": "changed", "recalibrate": true, "n": 3, "neg": -4, "big": u64::MAX,
            "x": 2.0, "tiny": 5e-324, "neg0": -0.0, "third": 1.0 / 3.0, "none": null,
            "lines": [{"cycles_per_rev": 12.0, "p": 1e-300}], "empty": [], "nested": {"a": {"b": [1, 2.5]}},
        });
        let back = round_trip(&v);
        assert_eq!(back, v);
        assert_eq!(back.to_string(), v.to_string());
        assert_eq!(back["neg0"].as_f64().unwrap().to_bits(), (-0.0f64).to_bits());
        assert!(back["x"].is_f64() && back["n"].is_u64() && back["neg"].is_i64());
    }

    #[test]
    fn bytes_cut_short_or_of_another_kind_do_not_decode() {
        let mut w = Writer::default();
        w.value(&json!({"a": [1.5, "b"]}));
        let bytes = w.into_bytes();
        for n in 0..bytes.len() {
            assert_eq!(Reader::new(&bytes[..n]).value(), Err(Malformed), "cut at {n}");
        }
        assert_eq!(Reader::new(&[9]).value(), Err(Malformed));
        assert_eq!(Reader::new(&[7, 255, 255, 255, 255, 255, 255, 255, 255]).value(), Err(Malformed));
        let deep: Vec<u8> = std::iter::repeat_n([7u8, 1, 0, 0, 0, 0, 0, 0, 0], 40).flatten().chain([0]).collect();
        assert_eq!(Reader::new(&deep).value(), Err(Malformed));
    }

    proptest! {
        #[test]
        fn every_f64_comes_back_bit_for_bit(bits in any::<u64>(), flag in any::<bool>()) {
            let v = f64::from_bits(bits);
            let mut w = Writer::default();
            w.f64(v);
            w.opt_f64(flag.then_some(v));
            let bytes = w.into_bytes();
            let mut r = Reader::new(&bytes);
            prop_assert_eq!(r.f64().unwrap().to_bits(), bits);
            prop_assert_eq!(r.opt_f64().unwrap().map(f64::to_bits), flag.then_some(bits));
            prop_assert!(r.end().is_ok());
        }
    }
}
