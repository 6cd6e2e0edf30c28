//! A minimal unpickler for the `data.pkl` of a PyTorch zip checkpoint.
//!
//! It evaluates only what `torch.save(state_dict)` writes: dicts (plain and
//! `collections.OrderedDict`), tuples, lists, scalars, strings, and tensors
//! rebuilt by `torch._utils._rebuild_tensor_v2` from persistent storage ids.
//! Any other callable is kept as an opaque [`Value::Object`] naming its
//! class, so a whole pickled model is recognised instead of silently giving
//! no tensors. Nothing is ever executed.

use std::collections::HashMap;

/// A tensor as the pickle describes it; its bytes live in the zip entry
/// `data/<storage_key>`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TensorRef {
    /// `FloatStorage`, `HalfStorage`, `LongStorage`, …
    pub storage_type: String,
    pub storage_key: String,
    /// Elements of the storage, as its persistent id declares them.
    pub storage_numel: Option<usize>,
    pub storage_offset: usize,
    pub shape: Vec<usize>,
    pub stride: Vec<usize>,
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Value {
    None,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
    Bytes(Vec<u8>),
    Tuple(Vec<Value>),
    List(Vec<Value>),
    Dict(Vec<(Value, Value)>),
    /// A `module.name` reference (class or function).
    Global(String, String),
    /// A storage pointer from BINPERSID: ("storage", type, key, location, numel).
    Storage {
        storage_type: String,
        key: String,
        /// The element count the persistent id declares.
        numel: Option<usize>,
    },
    Tensor(TensorRef),
    /// The result of calling or instantiating anything else, by class name.
    Object(String),
    /// The MARK sentinel on the stack.
    Mark,
}

/// Limits that keep a hostile pickle from exhausting the stack (deeply
/// nested containers are built, cloned and dropped recursively) or memory
/// (memo PUT/GET copy values, so shared references could multiply them).
const MAX_DEPTH: usize = 32;
const MAX_COPIED_NODES: usize = 1_000_000;

/// Nesting depth of containers (0 for a scalar). Recursion stays shallow
/// because every container is checked against [`MAX_DEPTH`] when built.
fn depth(v: &Value) -> usize {
    match v {
        Value::Tuple(x) | Value::List(x) => 1 + x.iter().map(depth).max().unwrap_or(0),
        Value::Dict(d) => {
            1 + d
                .iter()
                .map(|(k, v)| depth(k).max(depth(v)))
                .max()
                .unwrap_or(0)
        }
        _ => 0,
    }
}

fn nodes(v: &Value) -> usize {
    match v {
        Value::Tuple(x) | Value::List(x) => 1 + x.iter().map(nodes).sum::<usize>(),
        Value::Dict(d) => 1 + d.iter().map(|(k, v)| nodes(k) + nodes(v)).sum::<usize>(),
        _ => 1,
    }
}

/// Errors if putting `items` into a container would nest deeper than [`MAX_DEPTH`].
fn check_nesting(items: &[Value], pos: usize) -> Result<(), String> {
    if items.iter().any(|v| depth(v) + 1 > MAX_DEPTH) {
        return err(pos, format!("containers nested deeper than {MAX_DEPTH}"));
    }
    Ok(())
}

fn err<T>(pos: usize, msg: impl std::fmt::Display) -> Result<T, String> {
    Err(format!("data.pkl byte {pos}: {msg}"))
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        match self.bytes.get(self.pos..self.pos.saturating_add(n)) {
            Some(s) if self.pos.checked_add(n).is_some() => {
                self.pos += n;
                Ok(s)
            }
            _ => err(self.pos, format!("truncated (needs {n} more bytes)")),
        }
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(
            self.take(2)?.try_into().unwrap_or([0; 2]),
        ))
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().unwrap_or([0; 4]),
        ))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or([0; 8]),
        ))
    }
    fn line(&mut self) -> Result<String, String> {
        let rest = &self.bytes[self.pos.min(self.bytes.len())..];
        let Some(end) = rest.iter().position(|&b| b == b'\n') else {
            return err(self.pos, "unterminated text line");
        };
        let s = String::from_utf8_lossy(&rest[..end]).into_owned();
        self.pos += end + 1;
        Ok(s)
    }
    fn utf8(&mut self, n: usize) -> Result<String, String> {
        let at = self.pos;
        String::from_utf8(self.take(n)?.to_vec()).or_else(|_| err(at, "invalid UTF-8 string"))
    }
}

fn as_usize(v: &Value, what: &str, pos: usize) -> Result<usize, String> {
    match v {
        Value::Int(i) if *i >= 0 => Ok(*i as usize),
        _ => err(pos, format!("{what} is {v:?}, not a non-negative integer")),
    }
}

fn as_usizes(v: &Value, what: &str, pos: usize) -> Result<Vec<usize>, String> {
    match v {
        Value::Tuple(items) | Value::List(items) => {
            items.iter().map(|i| as_usize(i, what, pos)).collect()
        }
        _ => err(pos, format!("{what} is {v:?}, not a tuple of integers")),
    }
}

/// What calling `module.name(*args)` gives, for the callables a state dict uses.
fn call(module: &str, name: &str, args: Vec<Value>, pos: usize) -> Result<Value, String> {
    match (module, name) {
        ("collections", "OrderedDict") => Ok(Value::Dict(Vec::new())),
        ("torch._utils", "_rebuild_tensor_v2" | "_rebuild_tensor") => {
            let [storage, offset, shape, stride, ..] = args.as_slice() else {
                return err(pos, format!("{name} called with {} arguments", args.len()));
            };
            let Value::Storage {
                storage_type,
                key,
                numel,
            } = storage
            else {
                return err(
                    pos,
                    format!("{name}: first argument {storage:?} is not a storage"),
                );
            };
            Ok(Value::Tensor(TensorRef {
                storage_type: storage_type.clone(),
                storage_key: key.clone(),
                storage_numel: *numel,
                storage_offset: as_usize(offset, "storage offset", pos)?,
                shape: as_usizes(shape, "tensor size", pos)?,
                stride: as_usizes(stride, "tensor stride", pos)?,
            }))
        }
        // nn.Parameter wrapping a tensor: the tensor is what matters.
        ("torch._utils", "_rebuild_parameter" | "_rebuild_parameter_with_state") => {
            match args.into_iter().next() {
                Some(t @ Value::Tensor(_)) => Ok(t),
                other => err(pos, format!("{name} of {other:?}, not of a tensor")),
            }
        }
        _ => Ok(Value::Object(format!("{module}.{name}"))),
    }
}

/// Unpickles `bytes` (protocols 0–5, the opcodes torch uses).
pub(crate) fn unpickle(bytes: &[u8]) -> Result<Value, String> {
    let mut r = Reader { bytes, pos: 0 };
    let mut stack: Vec<Value> = Vec::new();
    let mut memo: HashMap<u32, Value> = HashMap::new();
    let mut copied_nodes = 0usize;
    // A memo copy, charged to the copy budget.
    let mut copy = |v: &Value, pos: usize| -> Result<Value, String> {
        copied_nodes += nodes(v);
        if copied_nodes > MAX_COPIED_NODES {
            return err(pos, "memo copies exceed the size limit (not a state dict)");
        }
        Ok(v.clone())
    };

    // Pops everything down to the last MARK (the MARK too).
    fn pop_mark(stack: &mut Vec<Value>, pos: usize) -> Result<Vec<Value>, String> {
        let Some(m) = stack.iter().rposition(|v| *v == Value::Mark) else {
            return err(pos, "MARK expected on the stack");
        };
        let items = stack.split_off(m + 1);
        stack.pop();
        Ok(items)
    }
    fn pop(stack: &mut Vec<Value>, pos: usize) -> Result<Value, String> {
        match stack.pop() {
            Some(Value::Mark) | None => err(pos, "stack underflow"),
            Some(v) => Ok(v),
        }
    }
    fn set_items(stack: &mut [Value], items: Vec<Value>, pos: usize) -> Result<(), String> {
        if !items.len().is_multiple_of(2) {
            return err(pos, "odd number of dict items");
        }
        check_nesting(&items, pos)?;
        match stack.last_mut() {
            Some(Value::Dict(d)) => {
                let mut it = items.into_iter();
                while let (Some(k), Some(v)) = (it.next(), it.next()) {
                    d.push((k, v));
                }
                Ok(())
            }
            // Items set on an opaque object (e.g. a module's __dict__) are dropped.
            Some(Value::Object(_)) => Ok(()),
            other => err(pos, format!("SETITEM(S) on {other:?}")),
        }
    }
    fn append(stack: &mut [Value], items: Vec<Value>, pos: usize) -> Result<(), String> {
        check_nesting(&items, pos)?;
        match stack.last_mut() {
            Some(Value::List(l)) => {
                l.extend(items);
                Ok(())
            }
            Some(Value::Object(_)) => Ok(()),
            other => err(pos, format!("APPEND(S) on {other:?}")),
        }
    }

    loop {
        let pos = r.pos;
        let op = r.u8()?;
        match op {
            0x80 => {
                r.u8()?; // PROTO n
            }
            0x95 => {
                r.u64()?; // FRAME length: framing is transparent here
            }
            b'.' => return pop(&mut stack, pos),
            b'(' => stack.push(Value::Mark),
            b'N' => stack.push(Value::None),
            0x88 => stack.push(Value::Bool(true)),
            0x89 => stack.push(Value::Bool(false)),
            b'J' => stack.push(Value::Int(r.u32()? as i32 as i64)),
            b'K' => stack.push(Value::Int(r.u8()? as i64)),
            b'M' => stack.push(Value::Int(r.u16()? as i64)),
            0x8a => {
                // LONG1: little-endian two's complement of n bytes
                let n = r.u8()? as usize;
                let b = r.take(n)?;
                if n > 8 {
                    return err(pos, "integer longer than 64 bits");
                }
                let mut v: i64 = 0;
                for (i, &byte) in b.iter().enumerate() {
                    v |= (byte as i64) << (8 * i);
                }
                if n > 0 && n < 8 && b[n - 1] & 0x80 != 0 {
                    v -= 1i64 << (8 * n);
                }
                stack.push(Value::Int(v));
            }
            b'I' => {
                let l = r.line()?;
                let v = match l.as_str() {
                    "00" => Value::Bool(false),
                    "01" => Value::Bool(true),
                    _ => Value::Int(l.parse().or_else(|_| err(pos, "bad INT"))?),
                };
                stack.push(v);
            }
            b'L' => {
                let l = r.line()?;
                let v = l
                    .trim_end_matches('L')
                    .parse()
                    .or_else(|_| err(pos, "bad LONG"))?;
                stack.push(Value::Int(v));
            }
            b'G' => stack.push(Value::Float(f64::from_be_bytes(
                r.take(8)?.try_into().unwrap_or([0; 8]),
            ))),
            b'F' => {
                let l = r.line()?;
                stack.push(Value::Float(l.parse().or_else(|_| err(pos, "bad FLOAT"))?));
            }
            b'X' => {
                let n = r.u32()? as usize;
                stack.push(Value::Str(r.utf8(n)?));
            }
            0x8c => {
                let n = r.u8()? as usize;
                stack.push(Value::Str(r.utf8(n)?));
            }
            0x8d => {
                let n = r.u64()? as usize;
                stack.push(Value::Str(r.utf8(n)?));
            }
            b'V' => stack.push(Value::Str(r.line()?)),
            b'S' => stack.push(Value::Str(r.line()?.trim_matches('\'').to_string())),
            b'B' => {
                let n = r.u32()? as usize;
                stack.push(Value::Bytes(r.take(n)?.to_vec()));
            }
            b'C' => {
                let n = r.u8()? as usize;
                stack.push(Value::Bytes(r.take(n)?.to_vec()));
            }
            0x8e => {
                let n = r.u64()? as usize;
                stack.push(Value::Bytes(r.take(n)?.to_vec()));
            }
            b')' => stack.push(Value::Tuple(Vec::new())),
            b't' => {
                let items = pop_mark(&mut stack, pos)?;
                check_nesting(&items, pos)?;
                stack.push(Value::Tuple(items));
            }
            0x85..=0x87 => {
                let n = (op - 0x84) as usize;
                if stack.len() < n {
                    return err(pos, "stack underflow");
                }
                let items = stack.split_off(stack.len() - n);
                if items.contains(&Value::Mark) {
                    return err(pos, "MARK inside a TUPLE1/2/3");
                }
                check_nesting(&items, pos)?;
                stack.push(Value::Tuple(items));
            }
            b']' => stack.push(Value::List(Vec::new())),
            b'l' => {
                let items = pop_mark(&mut stack, pos)?;
                check_nesting(&items, pos)?;
                stack.push(Value::List(items));
            }
            b'}' => stack.push(Value::Dict(Vec::new())),
            b'd' => {
                let items = pop_mark(&mut stack, pos)?;
                stack.push(Value::Dict(Vec::new()));
                set_items(&mut stack, items, pos)?;
            }
            b's' => {
                let v = pop(&mut stack, pos)?;
                let k = pop(&mut stack, pos)?;
                set_items(&mut stack, vec![k, v], pos)?;
            }
            b'u' => {
                let items = pop_mark(&mut stack, pos)?;
                set_items(&mut stack, items, pos)?;
            }
            b'a' => {
                let v = pop(&mut stack, pos)?;
                append(&mut stack, vec![v], pos)?;
            }
            b'e' => {
                let items = pop_mark(&mut stack, pos)?;
                append(&mut stack, items, pos)?;
            }
            b'c' => {
                let module = r.line()?;
                let name = r.line()?;
                stack.push(Value::Global(module, name));
            }
            0x93 => {
                let name = pop(&mut stack, pos)?;
                let module = pop(&mut stack, pos)?;
                match (module, name) {
                    (Value::Str(m), Value::Str(n)) => stack.push(Value::Global(m, n)),
                    _ => return err(pos, "STACK_GLOBAL of non-strings"),
                }
            }
            b'Q' => {
                // BINPERSID: torch's ('storage', StorageType, key, location, numel)
                let pid = pop(&mut stack, pos)?;
                let Value::Tuple(t) = &pid else {
                    return err(pos, format!("persistent id {pid:?} is not a tuple"));
                };
                match t.as_slice() {
                    [Value::Str(kind), Value::Global(_, ty), key, rest @ ..]
                        if kind == "storage" =>
                    {
                        let numel = match rest.get(1) {
                            Some(Value::Int(n)) if *n >= 0 => Some(*n as usize),
                            _ => None,
                        };
                        let key = match key {
                            Value::Str(s) => s.clone(),
                            Value::Int(i) => i.to_string(),
                            _ => return err(pos, format!("storage key {key:?}")),
                        };
                        stack.push(Value::Storage {
                            storage_type: ty.clone(),
                            key,
                            numel,
                        });
                    }
                    _ => return err(pos, format!("unsupported persistent id {pid:?}")),
                }
            }
            b'R' => {
                let args = pop(&mut stack, pos)?;
                let func = pop(&mut stack, pos)?;
                let Value::Tuple(args) = args else {
                    return err(pos, "REDUCE arguments are not a tuple");
                };
                let v = match func {
                    Value::Global(m, n) => call(&m, &n, args, pos)?,
                    other => Value::Object(format!("{other:?}")),
                };
                stack.push(v);
            }
            0x81 | 0x92 => {
                // NEWOBJ / NEWOBJ_EX: cls.__new__(cls, *args)
                if op == 0x92 {
                    pop(&mut stack, pos)?; // kwargs
                }
                pop(&mut stack, pos)?; // args
                let cls = pop(&mut stack, pos)?;
                stack.push(match cls {
                    Value::Global(m, n) if m == "collections" && n == "OrderedDict" => {
                        Value::Dict(Vec::new())
                    }
                    Value::Global(m, n) => Value::Object(format!("{m}.{n}")),
                    other => Value::Object(format!("{other:?}")),
                });
            }
            b'b' => {
                // BUILD: state for the object below; dicts (OrderedDict
                // `_metadata`) and opaque objects keep what they are.
                pop(&mut stack, pos)?;
                if stack.is_empty() {
                    return err(pos, "BUILD on an empty stack");
                }
            }
            b'q' | b'r' | 0x94 | b'p' => {
                let i = match op {
                    b'q' => r.u8()? as u32,
                    b'r' => r.u32()?,
                    0x94 => memo.len() as u32,
                    _ => r.line()?.parse().or_else(|_| err(pos, "bad PUT"))?,
                };
                let Some(top) = stack.last() else {
                    return err(pos, "PUT on an empty stack");
                };
                let v = copy(top, pos)?;
                memo.insert(i, v);
            }
            b'h' | b'j' | b'g' => {
                let i = match op {
                    b'h' => r.u8()? as u32,
                    b'j' => r.u32()?,
                    _ => r.line()?.parse().or_else(|_| err(pos, "bad GET"))?,
                };
                match memo.get(&i) {
                    Some(v) => {
                        let v = copy(v, pos)?;
                        stack.push(v);
                    }
                    None => return err(pos, format!("memo entry {i} not defined")),
                }
            }
            b'0' => {
                stack.pop();
            }
            b'2' => match stack.last() {
                Some(v) => {
                    let v = copy(v, pos)?;
                    stack.push(v);
                }
                None => return err(pos, "DUP on an empty stack"),
            },
            _ => return err(pos, format!("unsupported pickle opcode 0x{op:02x}")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_an_ordered_dict_of_one_tensor() {
        // Hand-assembled protocol-2 pickle of
        // OrderedDict(w = _rebuild_tensor_v2(storage('0', FloatStorage), 0, (2, 3), (3, 1), False, OrderedDict()))
        let mut p: Vec<u8> = vec![0x80, 2];
        p.extend(b"ccollections\nOrderedDict\nq\x00)R(X\x01\x00\x00\x00w");
        p.extend(b"ctorch._utils\n_rebuild_tensor_v2\n(");
        p.extend(b"(X\x07\x00\x00\x00storagectorch\nFloatStorage\nX\x01\x00\x00\x000X\x03\x00\x00\x00cpuK\x06tQ");
        p.extend(b"K\x00K\x02K\x03\x86K\x03K\x01\x86\x89h\x00)Rt");
        p.extend(b"Ru.");
        let v = unpickle(&p).unwrap();
        let Value::Dict(items) = v else {
            panic!("not a dict: {v:?}")
        };
        assert_eq!(items.len(), 1);
        assert_eq!(items[0].0, Value::Str("w".into()));
        assert_eq!(
            items[0].1,
            Value::Tensor(TensorRef {
                storage_type: "FloatStorage".into(),
                storage_key: "0".into(),
                storage_numel: Some(6),
                storage_offset: 0,
                shape: vec![2, 3],
                stride: vec![3, 1],
            })
        );
    }

    #[test]
    fn a_pickled_class_instance_stays_an_opaque_object() {
        // __main__.Net.__new__(Net) then BUILD with a dict: a whole-model pickle.
        let p = b"\x80\x02c__main__\nNet\nq\x00)\x81}X\x01\x00\x00\x00aK\x01sb.";
        assert_eq!(unpickle(p).unwrap(), Value::Object("__main__.Net".into()));
    }

    #[test]
    fn hostile_nesting_and_shared_references_are_refused() {
        // [[[[…]]]] 100 000 deep: would overflow the stack when dropped.
        let mut p = vec![0x80, 2];
        p.extend([b']'; 100_001]);
        p.extend([b'a'; 100_000]);
        p.push(b'.');
        assert!(unpickle(&p).unwrap_err().contains("nested deeper"));
        // L = [1]*8; then repeatedly L = [L, L] through the memo: 2^40 nodes
        // if copies were free.
        let mut p = vec![0x80, 2, b'('];
        p.extend([b'K', 1].repeat(8));
        p.extend([b'l', b'q', 0]);
        for _ in 0..40 {
            p.extend([b'h', 0, b'h', 0, 0x86, b'q', 0]);
        }
        p.push(b'.');
        let e = unpickle(&p).unwrap_err();
        assert!(
            e.contains("size limit") || e.contains("nested deeper"),
            "{e}"
        );
    }

    #[test]
    fn truncated_input_is_an_error_not_a_panic() {
        let p = b"\x80\x02ccollections\nOrderedDict\nq\x00)R(X\x10\x00\x00\x00ab";
        let e = unpickle(p).unwrap_err();
        assert!(e.contains("truncated"), "{e}");
        assert!(unpickle(b"").is_err());
        assert!(
            unpickle(b"\x80\x02\xff")
                .unwrap_err()
                .contains("opcode 0xff")
        );
    }
}
