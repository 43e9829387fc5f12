//! numpy's `.npy` array files (format versions 1 to 3).
//!
//! A file is the magic `\x93NUMPY`, a version, a header that is a Python
//! dict literal (`{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }`)
//! and the raw data; an object array (`descr` `|O`) stores a pickle of the
//! array instead, read with [`super::pickle`].

use super::pickle::{self, Dtype, NdArray};

/// What an `.npy` file holds.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Npy {
    /// An array of numbers.
    Numeric(NdArray),
    /// An object array whose items are numeric arrays (numpy's way of
    /// storing a ragged list of arrays).
    Objects {
        shape: Vec<usize>,
        items: Vec<NdArray>,
    },
}

const MAGIC: &[u8] = b"\x93NUMPY";

/// Parses an `.npy` file.
pub(crate) fn parse(bytes: &[u8]) -> Result<Npy, String> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err("not an .npy array (no \\x93NUMPY magic)".into());
    }
    let major = bytes[6];
    let (hlen, start) = match major {
        1 => (
            usize::from(u16::from_le_bytes([bytes[8], bytes[9]])),
            10usize,
        ),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err("truncated .npy header".into());
            }
            let n = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
            (n as usize, 12)
        }
        v => {
            return Err(format!(
                ".npy format version {v} is not supported (1 to 3 are)"
            ));
        }
    };
    let end = start
        .checked_add(hlen)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| format!("truncated .npy header: needs {hlen} bytes"))?;
    let header = String::from_utf8_lossy(&bytes[start..end]);
    let fields = parse_header(&header)?;
    let data = &bytes[end..];

    let descr = match fields.get("descr") {
        Some(Lit::Str(s)) => s.clone(),
        Some(_) => return Err("structured dtypes (a list in `descr`) are not supported".into()),
        None => return Err(".npy header has no `descr`".into()),
    };
    let fortran = match fields.get("fortran_order") {
        Some(Lit::Bool(b)) => *b,
        _ => return Err(".npy header has no boolean `fortran_order`".into()),
    };
    let shape = match fields.get("shape") {
        Some(Lit::Tuple(items)) => items
            .iter()
            .map(|d| match d {
                Lit::Int(n) => usize::try_from(*n).map_err(|_| format!("negative dimension {n}")),
                _ => Err("`shape` holds a non-integer".to_string()),
            })
            .collect::<Result<Vec<_>, _>>()?,
        _ => return Err(".npy header has no tuple `shape`".into()),
    };
    let dtype = Dtype::parse(&descr)?;
    if descr
        .trim_start_matches(['|', '<', '>', '='])
        .starts_with('O')
    {
        let p = pickle::load(data).map_err(|e| format!("object array: {e}"))?;
        let (_, vals) = p.object_array(p.root)?;
        let items = vals
            .iter()
            .enumerate()
            .map(|(i, v)| {
                p.array(*v)
                    .map_err(|e| format!("object array item {i}: {e}"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        return Ok(Npy::Objects { shape, items });
    }
    NdArray::from_raw(shape, &dtype, fortran, data).map(Npy::Numeric)
}

/// A Python literal in an `.npy` header.
#[derive(Debug, Clone, PartialEq)]
enum Lit {
    Str(String),
    Int(i64),
    Bool(bool),
    None,
    Tuple(Vec<Lit>),
    List(Vec<Lit>),
}

struct Fields(Vec<(String, Lit)>);

impl Fields {
    fn get(&self, k: &str) -> Option<&Lit> {
        self.0.iter().find(|(key, _)| key == k).map(|(_, v)| v)
    }
}

const MAX_DEPTH: usize = 16;

fn parse_header(h: &str) -> Result<Fields, String> {
    let mut p = LitParser {
        s: h.as_bytes(),
        pos: 0,
    };
    p.skip_ws();
    p.expect(b'{')?;
    let mut out = Vec::new();
    loop {
        p.skip_ws();
        if p.eat(b'}') {
            break;
        }
        let Lit::Str(key) = p.value(0)? else {
            return Err("an .npy header key is not a string".into());
        };
        p.skip_ws();
        p.expect(b':')?;
        let v = p.value(0)?;
        out.push((key, v));
        p.skip_ws();
        if !p.eat(b',') {
            p.skip_ws();
            p.expect(b'}')?;
            break;
        }
    }
    Ok(Fields(out))
}

struct LitParser<'a> {
    s: &'a [u8],
    pos: usize,
}

impl LitParser<'_> {
    fn skip_ws(&mut self) {
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    fn eat(&mut self, c: u8) -> bool {
        if self.s.get(self.pos) == Some(&c) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    fn expect(&mut self, c: u8) -> Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!(
                "malformed .npy header at character {}: expected `{}`",
                self.pos, c as char
            ))
        }
    }

    fn value(&mut self, depth: usize) -> Result<Lit, String> {
        if depth > MAX_DEPTH {
            return Err(".npy header nests too deeply".into());
        }
        self.skip_ws();
        let bad = |pos: usize| format!("malformed .npy header at character {pos}");
        match self.s.get(self.pos).copied() {
            Some(q @ (b'\'' | b'"')) => {
                self.pos += 1;
                let start = self.pos;
                while self.pos < self.s.len() && self.s[self.pos] != q {
                    self.pos += 1;
                }
                if self.pos >= self.s.len() {
                    return Err(bad(start));
                }
                let v = String::from_utf8_lossy(&self.s[start..self.pos]).into_owned();
                self.pos += 1;
                Ok(Lit::Str(v))
            }
            Some(open @ (b'(' | b'[')) => {
                self.pos += 1;
                let close = if open == b'(' { b')' } else { b']' };
                let mut items = Vec::new();
                loop {
                    self.skip_ws();
                    if self.eat(close) {
                        break;
                    }
                    items.push(self.value(depth + 1)?);
                    self.skip_ws();
                    if !self.eat(b',') {
                        self.skip_ws();
                        self.expect(close)?;
                        break;
                    }
                }
                Ok(if open == b'(' {
                    Lit::Tuple(items)
                } else {
                    Lit::List(items)
                })
            }
            Some(c) if c.is_ascii_digit() || c == b'-' => {
                let start = self.pos;
                self.pos += 1;
                while self.pos < self.s.len() && self.s[self.pos].is_ascii_digit() {
                    self.pos += 1;
                }
                let text = std::str::from_utf8(&self.s[start..self.pos]).map_err(|_| bad(start))?;
                let n = text.parse().map_err(|_| bad(start))?;
                // Python 2 wrote long integers with an `L` suffix.
                self.eat(b'L');
                Ok(Lit::Int(n))
            }
            Some(_) => {
                for (word, lit) in [
                    ("True", Lit::Bool(true)),
                    ("False", Lit::Bool(false)),
                    ("None", Lit::None),
                ] {
                    if self.s[self.pos..].starts_with(word.as_bytes()) {
                        self.pos += word.len();
                        return Ok(lit);
                    }
                }
                Err(bad(self.pos))
            }
            None => Err(bad(self.pos)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy(header: &str, data: &[u8]) -> Vec<u8> {
        let mut v = MAGIC.to_vec();
        v.extend([1, 0]);
        v.extend((header.len() as u16).to_le_bytes());
        v.extend(header.as_bytes());
        v.extend(data);
        v
    }

    #[test]
    fn reads_a_small_array() {
        let data: Vec<u8> = [1.0f64, 2.0, 3.0, 4.0, 5.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let f = npy(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }\n",
            &data,
        );
        let Npy::Numeric(a) = parse(&f).unwrap() else {
            panic!("numeric expected")
        };
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data[5], 6.0);
    }

    #[test]
    fn rejects_bad_headers_and_sizes() {
        let data = [0u8; 48];
        for (h, d, want) in [
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }",
                &data[..40],
                "needs 48 bytes",
            ),
            (
                "{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (2,), }",
                &data[..],
                "structured",
            ),
            (
                "{'descr': '<c16', 'fortran_order': False, 'shape': (3,), }",
                &data[..],
                "unsupported numpy dtype",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3",
                &data[..],
                "malformed",
            ),
            (
                "{'descr': '<f8', 'shape': (6,), }",
                &data[..],
                "fortran_order",
            ),
            (
                "{'descr': '<f8', 'fortran_order': False, 'shape': (-1,), }",
                &data[..],
                "negative",
            ),
        ] {
            let e = parse(&npy(h, d)).unwrap_err();
            assert!(e.contains(want), "{h}: {e}");
        }
        assert!(parse(b"\x93NUMPY").is_err());
        assert!(parse(b"PK\x03\x04 not npy at all").is_err());
    }
}
