//! A small pickle reader for exactly what a dict of numpy arrays needs.
//!
//! Python's pickle is a program for a stack machine. This reader runs the
//! opcodes of protocols 2 to 5 that pickling numbers, strings, bytes,
//! tuples, lists, dicts and numpy arrays produces, and calls only the few
//! functions numpy arrays are rebuilt with (`numpy.core.multiarray.
//! _reconstruct` and `numpy.dtype` with their `__setstate__`, numpy 2's
//! `numpy._core` spelling, protocol 5's `_frombuffer`, `_codecs.encode` for
//! bytes under protocol 2). Anything else is an error naming the byte
//! offset; no Python code is ever run.
//!
//! Objects live in an arena and the stack holds copyable handles, so
//! memoised objects are shared as in Python (a dtype rebuilt once and
//! fetched again keeps its byte order), cycles cannot leak or recurse, and
//! every allocation is bounded by the input: lengths are checked against
//! the bytes left before anything is read.

use std::collections::HashMap;

/// A failure, with the byte offset of the opcode that failed.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PickleError {
    pub offset: usize,
    pub reason: String,
}

impl std::fmt::Display for PickleError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "pickle byte {}: {}", self.offset, self.reason)
    }
}

type PResult<T> = std::result::Result<T, String>;

/// A value on the stack: small values inline, everything else a handle into
/// the arena.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Val {
    None,
    Bool(bool),
    Int(i64),
    Float(f64),
    Obj(usize),
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Dtype {
    /// numpy's kind letter: `f`, `i`, `u`, `b` or `O`.
    kind: u8,
    /// Bytes per element.
    size: usize,
    big_endian: bool,
}

impl Dtype {
    /// Parses a numpy type string such as `f8`, `<f4`, `>i2`, `|b1`, `O8`.
    pub(crate) fn parse(s: &str) -> PResult<Self> {
        let (big_endian, rest) = match s.as_bytes().first() {
            Some(b'>') => (true, &s[1..]),
            Some(b'<' | b'|' | b'=') => (false, &s[1..]),
            _ => (false, s),
        };
        let bad = || format!("unsupported numpy dtype `{s}`");
        let kind = *rest.as_bytes().first().ok_or_else(bad)?;
        let size: usize = if rest.len() == 1 && kind == b'O' {
            8
        } else {
            // `get` rather than indexing: the kind may be a multi-byte char.
            rest.get(1..).and_then(|d| d.parse().ok()).ok_or_else(bad)?
        };
        let ok = match kind {
            b'f' => matches!(size, 4 | 8),
            b'i' | b'u' => matches!(size, 1 | 2 | 4 | 8),
            b'b' => size == 1,
            b'O' => true,
            _ => false,
        };
        if !ok {
            return Err(bad());
        }
        Ok(Self {
            kind,
            size,
            big_endian,
        })
    }

    fn name(&self) -> String {
        format!(
            "{}{}{}",
            if self.big_endian { '>' } else { '<' },
            self.kind as char,
            self.size
        )
    }

    fn is_object(&self) -> bool {
        self.kind == b'O'
    }

    /// Converts raw element bytes to `f64`.
    fn decode(&self, raw: &[u8], out: &mut Vec<f64>) {
        let n = self.size;
        for c in raw.chunks_exact(n) {
            let mut b = [0u8; 8];
            b[..n].copy_from_slice(c);
            if self.big_endian {
                b[..n].reverse();
            }
            let v = match (self.kind, n) {
                (b'f', 8) => f64::from_le_bytes(b),
                (b'f', 4) => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                (b'i', _) => {
                    // Sign-extend the low n bytes.
                    let shift = 64 - 8 * n as u32;
                    ((i64::from_le_bytes(b) << shift) >> shift) as f64
                }
                (b'b', _) => f64::from(u8::from(b[0] != 0)),
                _ => u64::from_le_bytes(b) as f64,
            };
            out.push(v);
        }
    }
}

/// The payload of a rebuilt array.
#[derive(Debug, Clone, PartialEq)]
enum Payload {
    /// Raw bytes held by an arena object (a `Bytes`).
    Raw(usize),
    /// The items of an object array.
    Objects(Vec<Val>),
}

#[derive(Debug, Clone, PartialEq)]
struct Built {
    shape: Vec<usize>,
    dtype: Dtype,
    fortran: bool,
    payload: Payload,
}

#[derive(Debug, Clone, PartialEq)]
enum Obj {
    Str(String),
    Bytes(Vec<u8>),
    Tuple(Vec<Val>),
    List(Vec<Val>),
    Dict(Vec<(Val, Val)>),
    Global(String, String),
    Dtype(Dtype),
    /// An array from `_reconstruct`, filled by `BUILD` (`None` before).
    Array(Option<Built>),
}

/// A numeric array, converted to `f64` in row-major (C) order.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NdArray {
    pub shape: Vec<usize>,
    pub data: Vec<f64>,
    /// The numpy dtype it was stored as, for messages (`<f8`, `<f4`, ...).
    pub dtype: String,
}

impl NdArray {
    /// Builds an array from raw bytes, checking the byte count against the
    /// shape and reordering Fortran-ordered data.
    pub(crate) fn from_raw(
        shape: Vec<usize>,
        dtype: &Dtype,
        fortran: bool,
        raw: &[u8],
    ) -> PResult<Self> {
        if dtype.is_object() {
            return Err("object arrays hold no numbers".into());
        }
        let count = shape
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .ok_or_else(|| format!("shape {shape:?} overflows"))?;
        let want = count
            .checked_mul(dtype.size)
            .ok_or_else(|| format!("shape {shape:?} overflows"))?;
        if raw.len() != want {
            return Err(format!(
                "array of shape {shape:?} and dtype {} needs {want} bytes, found {}",
                dtype.name(),
                raw.len()
            ));
        }
        let mut data = Vec::with_capacity(count);
        dtype.decode(raw, &mut data);
        if fortran && shape.len() > 1 {
            data = fortran_to_c(&shape, &data);
        }
        Ok(Self {
            shape,
            data,
            dtype: dtype.name(),
        })
    }
}

/// Reorders column-major data of `shape` into row-major order.
fn fortran_to_c(shape: &[usize], data: &[f64]) -> Vec<f64> {
    let nd = shape.len();
    let mut fstride = vec![1usize; nd];
    for k in 1..nd {
        fstride[k] = fstride[k - 1] * shape[k - 1];
    }
    let mut idx = vec![0usize; nd];
    let mut out = Vec::with_capacity(data.len());
    for _ in 0..data.len() {
        let off: usize = idx.iter().zip(&fstride).map(|(i, s)| i * s).sum();
        out.push(data[off]);
        for k in (0..nd).rev() {
            idx[k] += 1;
            if idx[k] < shape[k] {
                break;
            }
            idx[k] = 0;
        }
    }
    out
}

/// The result of running a pickle: the arena and the value `STOP` returned.
#[derive(Debug)]
pub(crate) struct Pickle {
    arena: Vec<Obj>,
    /// The unpickled value.
    pub root: Val,
}

const MAX_PROTOCOL: u8 = 5;

/// Runs the pickle in `bytes`.
pub(crate) fn load(bytes: &[u8]) -> std::result::Result<Pickle, PickleError> {
    let mut vm = Vm {
        input: bytes,
        pos: 0,
        stack: Vec::new(),
        marks: Vec::new(),
        memo: HashMap::new(),
        arena: Vec::new(),
    };
    loop {
        let at = vm.pos;
        match vm.op() {
            Ok(Some(root)) => {
                return Ok(Pickle {
                    arena: vm.arena,
                    root,
                });
            }
            Ok(None) => {}
            Err(reason) => return Err(PickleError { offset: at, reason }),
        }
    }
}

struct Vm<'a> {
    input: &'a [u8],
    pos: usize,
    stack: Vec<Val>,
    marks: Vec<usize>,
    memo: HashMap<u32, Val>,
    arena: Vec<Obj>,
}

impl Vm<'_> {
    fn take(&mut self, n: usize) -> PResult<&[u8]> {
        let left = self.input.len() - self.pos;
        if n > left {
            return Err(format!("truncated: needs {n} more bytes, only {left} left"));
        }
        let s = &self.input[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn u8(&mut self) -> PResult<u8> {
        Ok(self.take(1)?[0])
    }

    fn u16(&mut self) -> PResult<u16> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self) -> PResult<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self) -> PResult<u64> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }

    /// A length read from the input, checked against the bytes left.
    fn len_u64(&mut self) -> PResult<usize> {
        let n = self.u64()?;
        usize::try_from(n).map_err(|_| format!("length {n} does not fit in memory"))
    }

    fn line(&mut self) -> PResult<String> {
        let rest = &self.input[self.pos..];
        let end = rest
            .iter()
            .position(|&b| b == b'\n')
            .ok_or("truncated: a GLOBAL name has no end of line")?;
        let s = std::str::from_utf8(&rest[..end])
            .map_err(|_| "a GLOBAL name is not UTF-8".to_string())?
            .to_string();
        self.pos += end + 1;
        Ok(s)
    }

    fn alloc(&mut self, o: Obj) -> Val {
        self.arena.push(o);
        Val::Obj(self.arena.len() - 1)
    }

    fn push_obj(&mut self, o: Obj) {
        let v = self.alloc(o);
        self.stack.push(v);
    }

    fn floor(&self) -> usize {
        self.marks.last().copied().unwrap_or(0)
    }

    fn pop(&mut self) -> PResult<Val> {
        if self.stack.len() <= self.floor() {
            return Err("stack underflow".into());
        }
        self.stack.pop().ok_or_else(|| "stack underflow".into())
    }

    fn top(&self) -> PResult<Val> {
        if self.stack.len() <= self.floor() {
            return Err("stack underflow".into());
        }
        self.stack
            .last()
            .copied()
            .ok_or_else(|| "stack underflow".into())
    }

    fn pop_mark(&mut self) -> PResult<Vec<Val>> {
        let m = self.marks.pop().ok_or("no MARK to pop to")?;
        Ok(self.stack.split_off(m.min(self.stack.len())))
    }

    fn obj(&self, v: Val) -> Option<&Obj> {
        match v {
            Val::Obj(i) => self.arena.get(i),
            _ => None,
        }
    }

    fn obj_mut(&mut self, v: Val) -> Option<&mut Obj> {
        match v {
            Val::Obj(i) => self.arena.get_mut(i),
            _ => None,
        }
    }

    fn memo_put(&mut self, idx: u32) -> PResult<()> {
        let v = self.top()?;
        self.memo.insert(idx, v);
        Ok(())
    }

    fn memo_get(&mut self, idx: u32) -> PResult<()> {
        let v = *self
            .memo
            .get(&idx)
            .ok_or_else(|| format!("memo entry {idx} was never stored"))?;
        self.stack.push(v);
        Ok(())
    }

    fn string(&mut self, n: usize) -> PResult<()> {
        let s = std::str::from_utf8(self.take(n)?)
            .map_err(|_| "a unicode string is not valid UTF-8".to_string())?
            .to_string();
        self.push_obj(Obj::Str(s));
        Ok(())
    }

    fn bytes(&mut self, n: usize) -> PResult<()> {
        let b = self.take(n)?.to_vec();
        self.push_obj(Obj::Bytes(b));
        Ok(())
    }

    /// Executes one opcode; returns the result at `STOP`.
    fn op(&mut self) -> PResult<Option<Val>> {
        let code = self
            .u8()
            .map_err(|_| "truncated: the pickle ends before STOP".to_string())?;
        match code {
            0x80 => {
                let p = self.u8()?;
                if p > MAX_PROTOCOL {
                    return Err(format!(
                        "pickle protocol {p} is newer than {MAX_PROTOCOL}, the newest supported"
                    ));
                }
            }
            0x95 => {
                self.u64()?;
            }
            b'.' => {
                let v = self.pop()?;
                return Ok(Some(v));
            }
            b'(' => self.marks.push(self.stack.len()),
            b')' => self.push_obj(Obj::Tuple(Vec::new())),
            b']' => self.push_obj(Obj::List(Vec::new())),
            b'}' => self.push_obj(Obj::Dict(Vec::new())),
            b't' => {
                let items = self.pop_mark()?;
                self.push_obj(Obj::Tuple(items));
            }
            0x85..=0x87 => {
                let n = usize::from(code - 0x84);
                let mut items = vec![Val::None; n];
                for k in (0..n).rev() {
                    items[k] = self.pop()?;
                }
                self.push_obj(Obj::Tuple(items));
            }
            b'l' => {
                let items = self.pop_mark()?;
                self.push_obj(Obj::List(items));
            }
            b'd' => {
                let items = self.pop_mark()?;
                let pairs = pairs(items)?;
                self.push_obj(Obj::Dict(pairs));
            }
            b'a' => {
                let v = self.pop()?;
                let t = self.top()?;
                match self.obj_mut(t) {
                    Some(Obj::List(l)) => l.push(v),
                    _ => return Err("APPEND to something not a list".into()),
                }
            }
            b'e' => {
                let items = self.pop_mark()?;
                let t = self.top()?;
                match self.obj_mut(t) {
                    Some(Obj::List(l)) => l.extend(items),
                    _ => return Err("APPENDS to something not a list".into()),
                }
            }
            b's' => {
                let v = self.pop()?;
                let k = self.pop()?;
                let t = self.top()?;
                match self.obj_mut(t) {
                    Some(Obj::Dict(d)) => d.push((k, v)),
                    _ => return Err("SETITEM on something not a dict".into()),
                }
            }
            b'u' => {
                let items = self.pop_mark()?;
                let new = pairs(items)?;
                let t = self.top()?;
                match self.obj_mut(t) {
                    Some(Obj::Dict(d)) => d.extend(new),
                    _ => return Err("SETITEMS on something not a dict".into()),
                }
            }
            b'q' => {
                let i = self.u8()?;
                self.memo_put(u32::from(i))?;
            }
            b'r' => {
                let i = self.u32()?;
                self.memo_put(i)?;
            }
            0x94 => {
                let i = u32::try_from(self.memo.len()).map_err(|_| "memo too large")?;
                self.memo_put(i)?;
            }
            b'h' => {
                let i = self.u8()?;
                self.memo_get(u32::from(i))?;
            }
            b'j' => {
                let i = self.u32()?;
                self.memo_get(i)?;
            }
            b'c' => {
                let module = self.line()?;
                let name = self.line()?;
                self.push_obj(Obj::Global(module, name));
            }
            0x93 => {
                let name = self.pop()?;
                let module = self.pop()?;
                match (self.obj(module), self.obj(name)) {
                    (Some(Obj::Str(m)), Some(Obj::Str(n))) => {
                        let g = Obj::Global(m.clone(), n.clone());
                        self.push_obj(g);
                    }
                    _ => return Err("STACK_GLOBAL needs two strings".into()),
                }
            }
            b'R' => {
                let args = self.pop()?;
                let func = self.pop()?;
                let v = self.reduce(func, args)?;
                self.stack.push(v);
            }
            b'b' => {
                let state = self.pop()?;
                let target = self.top()?;
                self.build(target, state)?;
            }
            b'J' => {
                let v = self.u32()? as i32;
                self.stack.push(Val::Int(i64::from(v)));
            }
            b'K' => {
                let v = self.u8()?;
                self.stack.push(Val::Int(i64::from(v)));
            }
            b'M' => {
                let v = self.u16()?;
                self.stack.push(Val::Int(i64::from(v)));
            }
            0x8a => {
                let n = usize::from(self.u8()?);
                if n > 8 {
                    return Err(format!("integer of {n} bytes is too large"));
                }
                let b = self.take(n)?;
                let mut a = [0u8; 8];
                a[..n].copy_from_slice(b);
                let v = if n == 0 {
                    0
                } else {
                    let shift = 64 - 8 * n as u32;
                    (i64::from_le_bytes(a) << shift) >> shift
                };
                self.stack.push(Val::Int(v));
            }
            b'N' => self.stack.push(Val::None),
            0x88 => self.stack.push(Val::Bool(true)),
            0x89 => self.stack.push(Val::Bool(false)),
            b'G' => {
                let b = self.take(8)?;
                let mut a = [0u8; 8];
                a.copy_from_slice(b);
                self.stack.push(Val::Float(f64::from_be_bytes(a)));
            }
            0x8c => {
                let n = usize::from(self.u8()?);
                self.string(n)?;
            }
            b'X' => {
                let n = self.u32()? as usize;
                self.string(n)?;
            }
            0x8d => {
                let n = self.len_u64()?;
                self.string(n)?;
            }
            b'C' | b'U' => {
                let n = usize::from(self.u8()?);
                self.bytes(n)?;
            }
            b'B' => {
                let n = self.u32()? as usize;
                self.bytes(n)?;
            }
            b'T' => {
                let n = self.u32()? as i32;
                let n = usize::try_from(n).map_err(|_| "negative string length".to_string())?;
                self.bytes(n)?;
            }
            0x8e | 0x96 => {
                let n = self.len_u64()?;
                self.bytes(n)?;
            }
            b'0' => {
                if self.stack.len() == self.floor() && !self.marks.is_empty() {
                    self.marks.pop();
                } else {
                    self.pop()?;
                }
            }
            b'1' => {
                self.pop_mark()?;
            }
            b'2' => {
                let v = self.top()?;
                self.stack.push(v);
            }
            0x98 => {}
            0x97 => {
                return Err(
                    "out-of-band buffer (NEXT_BUFFER): pickle with protocol 5 in-band".into(),
                );
            }
            other => {
                return Err(format!(
                    "unsupported pickle opcode 0x{other:02x} (this reader runs protocols 2 to 5 \
                     for dicts of numpy arrays)"
                ));
            }
        }
        Ok(None)
    }

    fn tuple(&self, v: Val, what: &str) -> PResult<Vec<Val>> {
        match self.obj(v) {
            Some(Obj::Tuple(t)) => Ok(t.clone()),
            _ => Err(format!("{what} is not a tuple")),
        }
    }

    fn str_of(&self, v: Val) -> Option<&str> {
        match self.obj(v) {
            Some(Obj::Str(s)) => Some(s),
            Some(Obj::Bytes(b)) => std::str::from_utf8(b).ok(),
            _ => None,
        }
    }

    fn shape(&self, v: Val) -> PResult<Vec<usize>> {
        let items = self.tuple(v, "an array shape")?;
        items
            .iter()
            .map(|d| match d {
                Val::Int(n) => usize::try_from(*n).map_err(|_| format!("negative dimension {n}")),
                _ => Err("an array shape holds a non-integer".into()),
            })
            .collect()
    }

    fn dtype(&self, v: Val) -> PResult<Dtype> {
        match self.obj(v) {
            Some(Obj::Dtype(d)) => Ok(d.clone()),
            _ => Err("expected a numpy dtype".into()),
        }
    }

    fn latin1(&self, s: Val) -> PResult<Vec<u8>> {
        let s = self.str_of(s).ok_or("expected a string to encode")?;
        s.chars()
            .map(|c| {
                u8::try_from(u32::from(c)).map_err(|_| format!("character {c:?} is not latin-1"))
            })
            .collect()
    }

    fn reduce(&mut self, func: Val, args: Val) -> PResult<Val> {
        let (module, name) = match self.obj(func) {
            Some(Obj::Global(m, n)) => (m.clone(), n.clone()),
            _ => return Err("REDUCE of something not a global function".into()),
        };
        let args = self.tuple(args, "the arguments of a call")?;
        let numpy_core = |m: &str, sub: &str| {
            m == format!("numpy.core.{sub}") || m == format!("numpy._core.{sub}")
        };
        let obj = match (module.as_str(), name.as_str()) {
            (m, "_reconstruct") if numpy_core(m, "multiarray") => Obj::Array(None),
            ("numpy", "dtype") => {
                let s = args
                    .first()
                    .and_then(|&a| self.str_of(a))
                    .ok_or("numpy.dtype called without a type string")?;
                Obj::Dtype(Dtype::parse(s)?)
            }
            ("_codecs", "encode") => {
                let enc = args.get(1).and_then(|&a| self.str_of(a)).unwrap_or("utf-8");
                let enc = enc.to_ascii_lowercase();
                if !matches!(enc.as_str(), "latin1" | "latin-1" | "iso-8859-1") {
                    return Err(format!(
                        "_codecs.encode with encoding {enc} is not supported"
                    ));
                }
                let s = *args.first().ok_or("_codecs.encode without a string")?;
                Obj::Bytes(self.latin1(s)?)
            }
            ("__builtin__" | "builtins", "bytes" | "bytearray") => match args.as_slice() {
                [] => Obj::Bytes(Vec::new()),
                [b] => match self.obj(*b) {
                    Some(Obj::Bytes(b)) => Obj::Bytes(b.clone()),
                    _ => return Err(format!("{module}.{name} of an unsupported argument")),
                },
                [s, _enc] => Obj::Bytes(self.latin1(*s)?),
                _ => return Err(format!("{module}.{name} with too many arguments")),
            },
            (m, "_frombuffer") if numpy_core(m, "numeric") => {
                let [buf, dtype, shape, order] = args.as_slice() else {
                    return Err("_frombuffer needs 4 arguments".into());
                };
                let Val::Obj(buf) = *buf else {
                    return Err("_frombuffer of something not bytes".into());
                };
                if !matches!(self.arena.get(buf), Some(Obj::Bytes(_))) {
                    return Err("_frombuffer of something not bytes".into());
                }
                Obj::Array(Some(Built {
                    shape: self.shape(*shape)?,
                    dtype: self.dtype(*dtype)?,
                    fortran: self.str_of(*order) == Some("F"),
                    payload: Payload::Raw(buf),
                }))
            }
            ("collections", "OrderedDict") if args.is_empty() => Obj::Dict(Vec::new()),
            _ => {
                return Err(format!(
                    "call to {module}.{name} is not supported (only numpy arrays, dtypes and \
                     plain containers are)"
                ));
            }
        };
        Ok(self.alloc(obj))
    }

    fn build(&mut self, target: Val, state: Val) -> PResult<()> {
        let st = self.tuple(state, "a BUILD state")?;
        match self.obj(target) {
            Some(Obj::Dtype(_)) => {
                // (version, byte order, subarray, names, fields, elsize,
                // alignment, flags): only the byte order matters here.
                let order = st.get(1).and_then(|&v| self.str_of(v)).unwrap_or("|");
                let big = order == ">";
                if let Some(Obj::Dtype(d)) = self.obj_mut(target) {
                    d.big_endian = big;
                }
                Ok(())
            }
            Some(Obj::Array(None)) => {
                // (version, shape, dtype, is_fortran, data); version 1 is the
                // only one numpy has written.
                let [_, shape, dtype, fortran, data] = st.as_slice() else {
                    return Err(format!(
                        "array state has {} fields, expected 5 (version 1)",
                        st.len()
                    ));
                };
                let shape = self.shape(*shape)?;
                let dtype = self.dtype(*dtype)?;
                let fortran = matches!(fortran, Val::Bool(true) | Val::Int(1));
                let payload = match self.obj(*data) {
                    Some(Obj::Bytes(_)) if !dtype.is_object() => match data {
                        Val::Obj(i) => Payload::Raw(*i),
                        _ => return Err("array data is not bytes".into()),
                    },
                    Some(Obj::Str(_)) if !dtype.is_object() => {
                        // A Python 2 str decoded as text: latin-1 gives the bytes.
                        let b = self.latin1(*data)?;
                        self.arena.push(Obj::Bytes(b));
                        Payload::Raw(self.arena.len() - 1)
                    }
                    Some(Obj::List(items)) if dtype.is_object() => Payload::Objects(items.clone()),
                    _ => {
                        return Err(format!(
                            "array data of dtype {} is of an unexpected kind",
                            dtype.name()
                        ));
                    }
                };
                if let Some(Obj::Array(a)) = self.obj_mut(target) {
                    *a = Some(Built {
                        shape,
                        dtype,
                        fortran,
                        payload,
                    });
                }
                Ok(())
            }
            Some(Obj::Array(Some(_))) => Err("BUILD of an array already built".into()),
            _ => Err("BUILD of an object that is neither a numpy array nor a dtype".into()),
        }
    }
}

fn pairs(items: Vec<Val>) -> PResult<Vec<(Val, Val)>> {
    if !items.len().is_multiple_of(2) {
        return Err("odd number of items for a dict".into());
    }
    Ok(items.chunks_exact(2).map(|c| (c[0], c[1])).collect())
}

impl Pickle {
    fn obj(&self, v: Val) -> Option<&Obj> {
        match v {
            Val::Obj(i) => self.arena.get(i),
            _ => None,
        }
    }

    /// The entries of a dict whose keys are strings (text or bytes).
    pub(crate) fn dict_entries(&self, v: Val) -> std::result::Result<Vec<(String, Val)>, String> {
        let Some(Obj::Dict(d)) = self.obj(v) else {
            return Err(format!("expected a dict, found {}", self.kind(v)));
        };
        d.iter()
            .map(|(k, v)| match self.obj(*k) {
                Some(Obj::Str(s)) => Ok((s.clone(), *v)),
                Some(Obj::Bytes(b)) => Ok((String::from_utf8_lossy(b).into_owned(), *v)),
                _ => Err(format!("a dict key is a {}, not a string", self.kind(*k))),
            })
            .collect()
    }

    /// A numeric numpy array, converted to `f64`.
    pub(crate) fn array(&self, v: Val) -> std::result::Result<NdArray, String> {
        match self.obj(v) {
            Some(Obj::Array(Some(b))) => match &b.payload {
                Payload::Raw(i) => match self.arena.get(*i) {
                    Some(Obj::Bytes(raw)) => {
                        NdArray::from_raw(b.shape.clone(), &b.dtype, b.fortran, raw)
                    }
                    _ => Err("array data is not bytes".into()),
                },
                Payload::Objects(_) => {
                    Err("an object array (dtype O), not an array of numbers".into())
                }
            },
            Some(Obj::Array(None)) => Err("a numpy array whose state was never set".into()),
            _ => Err(format!("expected a numpy array, found {}", self.kind(v))),
        }
    }

    /// The shape and items of an object array (as numpy stores ragged
    /// lists of arrays).
    pub(crate) fn object_array(
        &self,
        v: Val,
    ) -> std::result::Result<(Vec<usize>, Vec<Val>), String> {
        match self.obj(v) {
            Some(Obj::Array(Some(Built {
                shape,
                payload: Payload::Objects(items),
                ..
            }))) => Ok((shape.clone(), items.clone())),
            _ => Err(format!("expected an object array, found {}", self.kind(v))),
        }
    }

    /// Words for what `v` is, for messages.
    pub(crate) fn kind(&self, v: Val) -> String {
        match v {
            Val::None => "None".into(),
            Val::Bool(_) => "bool".into(),
            Val::Int(_) => "int".into(),
            Val::Float(_) => "float".into(),
            Val::Obj(_) => match self.obj(v) {
                Some(Obj::Str(_)) => "str".into(),
                Some(Obj::Bytes(_)) => "bytes".into(),
                Some(Obj::Tuple(_)) => "tuple".into(),
                Some(Obj::List(_)) => "list".into(),
                Some(Obj::Dict(_)) => "dict".into(),
                Some(Obj::Global(m, n)) => format!("{m}.{n}"),
                Some(Obj::Dtype(d)) => format!("dtype {}", d.name()),
                Some(Obj::Array(Some(b))) => {
                    format!("numpy array {:?} of {}", b.shape, b.dtype.name())
                }
                Some(Obj::Array(None)) => "numpy array without state".into(),
                None => "nothing".into(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dtype_parsing() {
        assert_eq!(Dtype::parse("<f8").unwrap().size, 8);
        assert!(Dtype::parse(">i2").unwrap().big_endian);
        assert!(Dtype::parse("O").unwrap().is_object());
        assert!(Dtype::parse("c16").is_err());
        assert!(Dtype::parse("f3").is_err());
        assert!(Dtype::parse("").is_err());
        assert!(Dtype::parse("\u{e9}8").is_err());
        assert!(Dtype::parse(">\u{e9}").is_err());
    }

    #[test]
    fn decodes_every_integer_width_and_order() {
        let mut out = Vec::new();
        Dtype::parse("<i2")
            .unwrap()
            .decode(&(-3i16).to_le_bytes(), &mut out);
        Dtype::parse(">i4")
            .unwrap()
            .decode(&(-70000i32).to_be_bytes(), &mut out);
        Dtype::parse(">f4")
            .unwrap()
            .decode(&1.5f32.to_be_bytes(), &mut out);
        Dtype::parse("u1").unwrap().decode(&[200], &mut out);
        assert_eq!(out, vec![-3.0, -70000.0, 1.5, 200.0]);
    }

    #[test]
    fn fortran_order_is_transposed() {
        // [[1, 2, 3], [4, 5, 6]] stored column-major.
        let raw: Vec<u8> = [1.0f64, 4.0, 2.0, 5.0, 3.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let a = NdArray::from_raw(vec![2, 3], &Dtype::parse("<f8").unwrap(), true, &raw).unwrap();
        assert_eq!(a.data, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    }

    #[test]
    fn python2_style_strings_and_lists() {
        // PROTO 2, MARK, SHORT_BINSTRING 'ab', BININT1 7, LIST... built as
        // {'ab': [7, 1.5]} with DICT.
        let mut p = vec![
            0x80, 2, b'(', b'U', 2, b'a', b'b', b']', b'K', 7, b'a', b'G',
        ];
        p.extend(1.5f64.to_be_bytes());
        p.extend([b'a', b'd', b'.']);
        let pk = load(&p).unwrap();
        let e = pk.dict_entries(pk.root).unwrap();
        assert_eq!(e[0].0, "ab");
        assert_eq!(pk.kind(e[0].1), "list");
    }

    #[test]
    fn malformed_programs_fail_without_panicking() {
        let cases: &[&[u8]] = &[
            b"",
            &[0x80, 9],
            &[0x80, 2, b'.'],
            &[0x80, 2, b'h', 3, b'.'],
            &[0x80, 2, b'a'],
            &[
                0x80, 2, 0x8e, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x7f,
            ],
            &[0x80, 2, b'X', 0xff, 0xff, 0xff, 0xff],
            &[
                0x80, 2, b'c', b'o', b's', b'\n', b's', b'y', b's', b't', b'e', b'm', b'\n', b')',
                b'R', b'.',
            ],
            &[0x80, 2, b'N', b'N', b'b', b'.'],
            &[0x80, 2, b'(', b'K', 1, b'u', b'.'],
            &[0x80, 2, b'T', 0xff, 0xff, 0xff, 0xff],
            &[0x80, 2, 0x8a, 200],
            &[0x80, 5, 0x97, b'.'],
        ];
        for c in cases {
            let err = load(c).and_then(|p| {
                p.dict_entries(p.root)
                    .map_err(|reason| PickleError { offset: 0, reason })
            });
            assert!(err.is_err(), "{c:?} should fail");
        }
    }
}
