//! A strict protobuf reader for the ONNX messages a policy may hold.
//!
//! Protobuf readers (the `onnx` package, ONNX Runtime) merge a singular message field that occurs more than
//! once and keep the last copy of a singular scalar, and they skip fields they do not know. A checker that
//! reads a file differently from the runtime can be bypassed, so this reader refuses instead: every message
//! is read against its schema, a singular field may occur once, a field the schema does not list (or lists
//! as refused: subgraphs, functions, sparse or external data, training info) is an error, and a field with
//! the wrong wire type is an error (protobuf would skip it as unknown).

/// Wire types (protobuf encoding).
const VARINT: u8 = 0;
const I64: u8 = 1;
const LEN: u8 = 2;
const I32: u8 = 5;

/// How a schema field may occur.
#[derive(Clone, Copy)]
pub(super) enum Kind {
    /// At most once, with this wire type.
    One(u8),
    /// Any number of times, with this wire type (scalars also packed, as one length-delimited field).
    Many(u8),
    /// Never: a construct a policy may not use (the text says what it is).
    Refused(&'static str),
}

pub(super) const ONE_VARINT: Kind = Kind::One(VARINT);
pub(super) const ONE_I32: Kind = Kind::One(I32);
pub(super) const ONE_LEN: Kind = Kind::One(LEN);
pub(super) const MANY_VARINT: Kind = Kind::Many(VARINT);
pub(super) const MANY_I32: Kind = Kind::Many(I32);
pub(super) const MANY_I64: Kind = Kind::Many(I64);
pub(super) const MANY_LEN: Kind = Kind::Many(LEN);

/// A message's schema: its name (for errors) and its fields (number, name, kind).
pub(super) struct Schema {
    pub name: &'static str,
    pub fields: &'static [(u32, &'static str, Kind)],
}

/// One field's raw value.
#[derive(Clone, Copy)]
enum Raw<'a> {
    Number(u64),
    Bytes(&'a [u8]),
}

/// A message read against its schema: its fields in file order.
pub(super) struct Message<'a> {
    schema: &'static Schema,
    fields: Vec<(u32, Raw<'a>)>,
}

impl<'a> Message<'a> {
    /// Reads `bytes` as a `schema` message; refuses duplicates of singular fields, unknown or refused fields,
    /// wrong wire types, and malformed encoding.
    pub fn parse(bytes: &'a [u8], schema: &'static Schema) -> Result<Self, String> {
        let mut reader = Reader { bytes, at: 0 };
        let mut fields = Vec::new();
        let mut seen: Vec<u32> = Vec::new();
        while reader.at < bytes.len() {
            let key = reader.varint()?;
            let (number, wire) = (key >> 3, (key & 7) as u8);
            let raw = match wire {
                VARINT => Raw::Number(reader.varint()?),
                I64 => Raw::Number(u64::from_le_bytes(reader.take(8)?.try_into().expect("8 bytes"))),
                I32 => Raw::Number(u64::from(u32::from_le_bytes(reader.take(4)?.try_into().expect("4 bytes")))),
                LEN => {
                    let length = reader.varint()?;
                    Raw::Bytes(reader.take(length)?)
                }
                other => {
                    return Err(format!("the file is not a valid ONNX model (wire type {other} in {})", schema.name));
                }
            };
            let number = u32::try_from(number).map_err(|_| invalid("a field number out of range"))?;
            let Some(&(_, name, kind)) = schema.fields.iter().find(|(n, _, _)| *n == number) else {
                return Err(format!(
                    "the file has a field {number} in an ONNX {} that a policy may not have (unknown fields are \
                     refused: a reader would skip them)",
                    schema.name
                ));
            };
            match kind {
                Kind::Refused(what) => {
                    return Err(format!("the model holds {what} ({}.{name}); a policy may not", schema.name));
                }
                Kind::One(expected) => {
                    if wire != expected {
                        return Err(wrong_wire(schema, name));
                    }
                    if seen.contains(&number) {
                        return Err(format!(
                            "the file has the {}.{name} field more than once (a reader would merge the copies, \
                             and the check reads each field once); refused",
                            schema.name
                        ));
                    }
                    seen.push(number);
                }
                Kind::Many(expected) => {
                    // A repeated scalar may come packed, as one length-delimited field.
                    if wire != expected && !(wire == LEN && expected != LEN) {
                        return Err(wrong_wire(schema, name));
                    }
                }
            }
            fields.push((number, raw));
        }
        Ok(Self { schema, fields })
    }

    /// The bytes of singular length-delimited field `number`, if present.
    pub fn bytes(&self, number: u32) -> Option<&'a [u8]> {
        self.fields.iter().find_map(|(n, raw)| match raw {
            Raw::Bytes(bytes) if *n == number => Some(*bytes),
            _ => None,
        })
    }

    /// The text of singular string field `number` ("" when absent).
    pub fn text(&self, number: u32) -> Result<String, String> {
        let bytes = self.bytes(number).unwrap_or_default();
        String::from_utf8(bytes.to_vec())
            .map_err(|_| format!("the file has text that is not UTF-8 in a {}", self.schema.name))
    }

    /// Singular varint field `number` as a signed integer (int64/int32/enum), if present.
    pub fn int(&self, number: u32) -> Option<i64> {
        self.fields.iter().find_map(|(n, raw)| match raw {
            Raw::Number(value) if *n == number => Some(*value as i64),
            _ => None,
        })
    }

    /// Every occurrence of repeated length-delimited field `number` (messages, strings).
    pub fn all_bytes(&self, number: u32) -> Vec<&'a [u8]> {
        self.fields
            .iter()
            .filter_map(|(n, raw)| match raw {
                Raw::Bytes(bytes) if *n == number => Some(*bytes),
                _ => None,
            })
            .collect()
    }

    /// Every occurrence of repeated string field `number`.
    pub fn all_text(&self, number: u32) -> Result<Vec<String>, String> {
        self.all_bytes(number)
            .into_iter()
            .map(|bytes| {
                String::from_utf8(bytes.to_vec())
                    .map_err(|_| format!("the file has text that is not UTF-8 in a {}", self.schema.name))
            })
            .collect()
    }

    /// Every value of repeated varint field `number` (packed or not), as signed integers.
    pub fn all_ints(&self, number: u32) -> Result<Vec<i64>, String> {
        let mut values = Vec::new();
        for (n, raw) in &self.fields {
            match raw {
                Raw::Number(value) if *n == number => values.push(*value as i64),
                Raw::Bytes(packed) if *n == number => {
                    let mut reader = Reader { bytes: packed, at: 0 };
                    while reader.at < packed.len() {
                        values.push(reader.varint()? as i64);
                    }
                }
                _ => {}
            }
        }
        Ok(values)
    }

    /// How many values repeated fixed-width field `number` holds (packed or not), `width` bytes each.
    pub fn count_fixed(&self, number: u32, width: usize) -> Result<usize, String> {
        let mut count = 0;
        for (n, raw) in &self.fields {
            match raw {
                Raw::Number(_) if *n == number => count += 1,
                Raw::Bytes(packed) if *n == number => {
                    if packed.len() % width != 0 {
                        return Err(invalid("a packed field of the wrong length"));
                    }
                    count += packed.len() / width;
                }
                _ => {}
            }
        }
        Ok(count)
    }

    /// Every value of repeated fixed32 float field `number` (packed or not).
    pub fn all_floats(&self, number: u32) -> Result<Vec<f32>, String> {
        let mut values = Vec::new();
        for (n, raw) in &self.fields {
            match raw {
                Raw::Number(bits) if *n == number => values.push(f32::from_bits(*bits as u32)),
                Raw::Bytes(packed) if *n == number => {
                    if packed.len() % 4 != 0 {
                        return Err(invalid("a packed field of the wrong length"));
                    }
                    values.extend(packed.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes"))));
                }
                _ => {}
            }
        }
        Ok(values)
    }

    /// Whether field `number` occurs at all.
    pub fn has(&self, number: u32) -> bool {
        self.fields.iter().any(|(n, _)| *n == number)
    }
}

fn invalid(what: &str) -> String {
    format!("the file is not a valid ONNX model ({what})")
}

fn wrong_wire(schema: &Schema, name: &str) -> String {
    format!(
        "the file's {}.{name} field has the wrong encoding (a reader would skip it as unknown); refused",
        schema.name
    )
}

/// Reads varints and length-delimited slices from a message's bytes.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn varint(&mut self) -> Result<u64, String> {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = *self.bytes.get(self.at).ok_or_else(|| invalid("truncated"))?;
            self.at += 1;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(invalid("bad varint"))
    }

    fn take(&mut self, count: u64) -> Result<&'a [u8], String> {
        let end = usize::try_from(count)
            .ok()
            .and_then(|n| self.at.checked_add(n))
            .filter(|&end| end <= self.bytes.len())
            .ok_or_else(|| invalid("a field runs past its end"))?;
        let slice = &self.bytes[self.at..end];
        self.at = end;
        Ok(slice)
    }
}
