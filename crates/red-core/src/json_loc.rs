//! Locating problems in JSON text: which value a line and column fall in
//! (`trajectories[2].observations[5][1]`), and the first number JSON or
//! `f64` cannot hold (`NaN`, `Infinity`, `1e400`).
//!
//! The scanner is lenient: it follows strings, brackets, commas and colons
//! and never fails, so it can describe a position even in broken text.

use std::fmt;

/// One step of a path into a JSON document.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Seg {
    Key(String),
    Index(usize),
}

/// A path from the root of a JSON document to a value.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct JsonPath(pub Vec<Seg>);

impl JsonPath {
    pub(crate) fn is_root(&self) -> bool {
        self.0.is_empty()
    }

    /// The trajectory and step a path points into, when it does:
    /// `trajectories[t]` and `trajectories[t].<observations|actions|rewards>[k]`.
    pub(crate) fn trajectory_step(&self) -> (Option<usize>, Option<usize>) {
        match self.0.as_slice() {
            [Seg::Key(k), Seg::Index(t), rest @ ..] if k == "trajectories" => {
                let step = match rest {
                    [Seg::Key(f), Seg::Index(s), ..]
                        if matches!(f.as_str(), "observations" | "actions" | "rewards") =>
                    {
                        Some(*s)
                    }
                    _ => None,
                };
                (Some(*t), step)
            }
            _ => (None, None),
        }
    }

    /// ` (at <path>)`, or nothing at the root.
    pub(crate) fn describe_in(&self) -> String {
        if self.is_root() {
            String::new()
        } else {
            format!(" (at {self})")
        }
    }
}

impl fmt::Display for JsonPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return f.write_str("the top level");
        }
        for (i, s) in self.0.iter().enumerate() {
            match s {
                Seg::Key(k) if i == 0 => write!(f, "{k}")?,
                Seg::Key(k) => write!(f, ".{k}")?,
                Seg::Index(n) => write!(f, "[{n}]")?,
            }
        }
        Ok(())
    }
}

/// The byte offset of serde_json's 1-based `line` and `column` (the
/// column counts the bytes of that line read so far).
pub(crate) fn offset_of(text: &str, line: usize, column: usize) -> usize {
    let mut start = 0;
    for _ in 1..line.max(1) {
        match text[start..].find('\n') {
            Some(i) => start += i + 1,
            None => return text.len(),
        }
    }
    (start + column).min(text.len())
}

/// A number that JSON cannot hold (`NaN`, `Infinity`) or that overflows
/// `f64`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BadNumber {
    pub offset: usize,
    pub line: usize,
    pub column: usize,
    pub token: String,
    pub path: JsonPath,
    /// Whether the token is valid JSON that overflows (`1e400`) rather than
    /// a non-JSON word (`NaN`).
    pub overflow: bool,
}

impl BadNumber {
    pub(crate) fn problem(&self) -> String {
        if self.overflow {
            format!(
                "the number {} is out of range for f64 (it would be infinite); \
                 demonstrations must be finite",
                self.token
            )
        } else {
            format!(
                "`{}` is not a finite number: JSON has no NaN or infinity, and \
                 demonstrations must be finite",
                self.token
            )
        }
    }
}

enum Frame {
    Object { key: Option<String>, want_key: bool },
    Array { index: usize },
}

struct Scanner<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
    line_start: usize,
    stack: Vec<Frame>,
}

enum Event {
    /// A literal (number or word) at `start..end`.
    Literal {
        start: usize,
        end: usize,
    },
    Done,
}

impl<'a> Scanner<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            bytes: text.as_bytes(),
            pos: 0,
            line: 1,
            line_start: 0,
            stack: Vec::new(),
        }
    }

    fn path(&self) -> JsonPath {
        JsonPath(
            self.stack
                .iter()
                .filter_map(|f| match f {
                    Frame::Object { key, .. } => key.clone().map(Seg::Key),
                    Frame::Array { index } => Some(Seg::Index(*index)),
                })
                .collect(),
        )
    }

    /// Advances to the next literal, or to `limit`.
    fn next(&mut self, limit: usize) -> Event {
        let limit = limit.min(self.bytes.len());
        while self.pos < limit {
            let c = self.bytes[self.pos];
            match c {
                b'\n' => {
                    self.pos += 1;
                    self.line += 1;
                    self.line_start = self.pos;
                }
                b'{' => {
                    self.stack.push(Frame::Object {
                        key: None,
                        want_key: true,
                    });
                    self.pos += 1;
                }
                b'[' => {
                    self.stack.push(Frame::Array { index: 0 });
                    self.pos += 1;
                }
                b'}' | b']' => {
                    self.stack.pop();
                    self.pos += 1;
                }
                b',' => {
                    match self.stack.last_mut() {
                        Some(Frame::Array { index }) => *index += 1,
                        Some(Frame::Object { want_key, .. }) => *want_key = true,
                        None => {}
                    }
                    self.pos += 1;
                }
                b':' => {
                    if let Some(Frame::Object { want_key, .. }) = self.stack.last_mut() {
                        *want_key = false;
                    }
                    self.pos += 1;
                }
                b'"' => {
                    let start = self.pos + 1;
                    let mut i = start;
                    while i < limit && self.bytes[i] != b'"' {
                        i += if self.bytes[i] == b'\\' { 2 } else { 1 };
                    }
                    let end = i.min(limit);
                    if let Some(Frame::Object { key, want_key }) = self.stack.last_mut()
                        && *want_key
                    {
                        *key = Some(String::from_utf8_lossy(&self.bytes[start..end]).into_owned());
                    }
                    self.pos = (end + 1).min(limit);
                }
                c if c.is_ascii_alphanumeric() || matches!(c, b'+' | b'-' | b'.') => {
                    let start = self.pos;
                    let mut end = start;
                    while end < limit
                        && (self.bytes[end].is_ascii_alphanumeric()
                            || matches!(self.bytes[end], b'+' | b'-' | b'.'))
                    {
                        end += 1;
                    }
                    self.pos = end;
                    return Event::Literal { start, end };
                }
                // Whitespace, or a byte no JSON has here (broken text).
                _ => self.pos += 1,
            }
        }
        Event::Done
    }
}

/// The path of the value at byte `offset` of `text`.
pub(crate) fn path_at(text: &str, offset: usize) -> JsonPath {
    let mut s = Scanner::new(text);
    while let Event::Literal { .. } = s.next(offset) {}
    s.path()
}

fn is_json_number(t: &str) -> bool {
    let b = t.as_bytes();
    let mut i = usize::from(b.first() == Some(&b'-'));
    let digits = |i: &mut usize| {
        let s = *i;
        while *i < b.len() && b[*i].is_ascii_digit() {
            *i += 1;
        }
        *i > s
    };
    if !digits(&mut i) {
        return false;
    }
    if i < b.len() && b[i] == b'.' {
        i += 1;
        if !digits(&mut i) {
            return false;
        }
    }
    if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
        i += 1;
        if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
            i += 1;
        }
        if !digits(&mut i) {
            return false;
        }
    }
    i == b.len()
}

/// The first `NaN`/`Infinity`-like word or overflowing number in `text`.
pub(crate) fn first_non_finite(text: &str) -> Option<BadNumber> {
    let mut s = Scanner::new(text);
    while let Event::Literal { start, end } = s.next(text.len()) {
        let token = &text[start..end];
        let word = token.trim_start_matches(['-', '+']).to_ascii_lowercase();
        let overflow = is_json_number(token) && token.parse::<f64>().is_ok_and(|v| !v.is_finite());
        if overflow || matches!(word.as_str(), "nan" | "inf" | "infinity") {
            return Some(BadNumber {
                offset: start,
                line: s.line,
                column: start - s.line_start + 1,
                token: token.to_string(),
                path: s.path(),
                overflow,
            });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_paths() {
        let t = r#"{"a": 1, "trajectories": [{"x": 2}, {"actions": [[1], [2, 3]]}]}"#;
        let at = t.find("3]").unwrap();
        let p = path_at(t, at);
        assert_eq!(p.to_string(), "trajectories[1].actions[1][1]");
        assert_eq!(p.trajectory_step(), (Some(1), Some(1)));
        assert!(path_at(t, 0).is_root());
    }

    #[test]
    fn finds_non_finite_tokens_outside_strings() {
        let t = "{\"NaN\": \"Infinity\",\n \"v\": [1.5, -Infinity]}";
        let b = first_non_finite(t).unwrap();
        assert_eq!((b.line, b.column, b.token.as_str()), (2, 13, "-Infinity"));
        assert_eq!(b.path.to_string(), "v[1]");
        let b = first_non_finite("[1e308, 2E+400]").unwrap();
        assert!(b.overflow && b.token == "2E+400");
        assert!(first_non_finite("[1e-400, 0.5, true, null]").is_none());
    }

    #[test]
    fn offsets_of_lines_and_columns() {
        let t = "ab\ncde\nf";
        assert_eq!(offset_of(t, 2, 2), 5);
        assert_eq!(offset_of(t, 9, 9), t.len());
    }

    #[test]
    fn scanner_survives_garbage() {
        for t in ["", "\"", "{\"a", "[[[", "}}]]", "\u{e9}\u{e9}", "{\"a\\"] {
            let _ = path_at(t, t.len());
            let _ = first_non_finite(t);
        }
    }
}
