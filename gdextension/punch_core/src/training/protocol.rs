//! Wire format between the trainer and the training server (documented in docs/protocol.md).
//!
//! A message is `u32 header_bytes | u32 payload_bytes | header | payload`, lengths little-endian. The header
//! is a UTF-8 JSON object with a `type` and an `arrays` list of `{"name", "shape"}`; the payload is those
//! arrays' little-endian f32 values, concatenated in that order. Lengths are checked against hard limits
//! before anything is allocated.

use std::io::{Read, Write};

use serde_json::{Map, Value, json};

/// Bumped on any change to the framing or to a message's fields.
pub const PROTOCOL_VERSION: u32 = 8;
/// Largest header accepted, bytes.
pub const MAX_HEADER_BYTES: usize = 64 * 1024;
/// Largest payload accepted, bytes (256 slots x 400 frames x 50 features x 4 bytes is about 20 MB).
pub const MAX_PAYLOAD_BYTES: usize = 256 * 1024 * 1024;

/// A named f32 array with a shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    pub name: String,
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

impl Array {
    pub fn new(name: &str, shape: Vec<usize>, data: Vec<f32>) -> Self {
        debug_assert_eq!(shape.iter().product::<usize>(), data.len());
        Self { name: name.to_string(), shape, data }
    }
}

/// A decoded message: its JSON header (without `arrays`) and its arrays.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    pub header: Map<String, Value>,
    pub arrays: Vec<Array>,
}

/// What went wrong reading a message. `Framing` errors leave the stream unusable (the connection must be
/// closed); `Content` errors concern one well-framed message, which can be answered with an error reply.
#[derive(Debug, thiserror::Error)]
pub enum ProtocolError {
    #[error("connection closed")]
    Closed,
    #[error("i/o error: {0}")]
    Io(#[from] std::io::Error),
    #[error("framing error: {0}")]
    Framing(String),
    #[error("bad message: {0}")]
    Content(String),
}

impl Message {
    pub fn new(message_type: &str) -> Self {
        let mut header = Map::new();
        header.insert("type".into(), Value::String(message_type.into()));
        Self { header, arrays: Vec::new() }
    }

    /// Sets a header field (builder style).
    pub fn with(mut self, key: &str, value: Value) -> Self {
        self.header.insert(key.into(), value);
        self
    }

    pub fn with_array(mut self, array: Array) -> Self {
        self.arrays.push(array);
        self
    }

    /// The message `type` ("" when absent).
    pub fn message_type(&self) -> &str {
        self.header.get("type").and_then(Value::as_str).unwrap_or("")
    }

    /// The array called `name` with exactly `shape`, or a Content error saying what was wrong.
    pub fn array(&self, name: &str, shape: &[usize]) -> Result<&Array, ProtocolError> {
        let array = self
            .arrays
            .iter()
            .find(|a| a.name == name)
            .ok_or_else(|| ProtocolError::Content(format!("missing array '{name}'")))?;
        if array.shape != shape {
            return Err(ProtocolError::Content(format!(
                "array '{name}' has shape {:?}, expected {shape:?}",
                array.shape
            )));
        }
        if let Some(index) = array.data.iter().position(|v| !v.is_finite()) {
            return Err(ProtocolError::Content(format!("array '{name}' has a non-finite value at {index}")));
        }
        Ok(array)
    }

    /// Encodes the message into one buffer.
    pub fn encode(&self) -> Vec<u8> {
        let mut header = self.header.clone();
        let descriptors: Vec<Value> = self.arrays.iter().map(|a| json!({"name": a.name, "shape": a.shape})).collect();
        header.insert("arrays".into(), Value::Array(descriptors));
        let header_bytes = Value::Object(header).to_string().into_bytes();
        let payload_len: usize = self.arrays.iter().map(|a| a.data.len() * 4).sum();
        let mut buffer = Vec::with_capacity(8 + header_bytes.len() + payload_len);
        buffer.extend_from_slice(&(header_bytes.len() as u32).to_le_bytes());
        buffer.extend_from_slice(&(payload_len as u32).to_le_bytes());
        buffer.extend_from_slice(&header_bytes);
        for array in &self.arrays {
            for value in &array.data {
                buffer.extend_from_slice(&value.to_le_bytes());
            }
        }
        buffer
    }

    pub fn write_to(&self, writer: &mut impl Write) -> std::io::Result<()> {
        writer.write_all(&self.encode())?;
        writer.flush()
    }

    /// Reads one message. A clean end of stream before the first byte is `Closed`.
    pub fn read_from(reader: &mut impl Read) -> Result<Self, ProtocolError> {
        let mut lengths = [0u8; 8];
        read_exact_or_closed(reader, &mut lengths)?;
        let (header_len, payload_len) = frame_lengths(&lengths, MAX_PAYLOAD_BYTES)?;
        let header = read_growing(reader, header_len)?;
        let payload = read_growing(reader, payload_len)?;
        Self::decode_parts(&header, &payload)
    }

    /// Decodes a header and payload (already framed). Every inconsistency is a Content error.
    pub fn decode_parts(header: &[u8], payload: &[u8]) -> Result<Self, ProtocolError> {
        let content = ProtocolError::Content;
        let value: Value = serde_json::from_slice(header).map_err(|e| content(format!("header is not JSON: {e}")))?;
        let Value::Object(mut header) = value else {
            return Err(content("header is not a JSON object".into()));
        };
        if !matches!(header.get("type"), Some(Value::String(_))) {
            return Err(content("header has no string 'type'".into()));
        }
        let descriptors = match header.remove("arrays") {
            None => Vec::new(),
            Some(Value::Array(list)) => list,
            Some(_) => return Err(content("'arrays' must be a list".into())),
        };
        let mut arrays = Vec::with_capacity(descriptors.len().min(16));
        let mut offset = 0usize;
        for descriptor in descriptors {
            let name =
                descriptor.get("name").and_then(Value::as_str).ok_or_else(|| content("array without a name".into()))?;
            let shape: Vec<usize> = descriptor
                .get("shape")
                .and_then(Value::as_array)
                .ok_or_else(|| content(format!("array '{name}' has no shape")))?
                .iter()
                .map(|d| d.as_u64().map(|d| d as usize))
                .collect::<Option<_>>()
                .ok_or_else(|| content(format!("array '{name}' shape must be non-negative integers")))?;
            let count = shape
                .iter()
                .try_fold(1usize, |acc, &d| acc.checked_mul(d))
                .filter(|&n| n <= payload.len() / 4)
                .ok_or_else(|| content(format!("array '{name}' shape {shape:?} is larger than the payload")))?;
            let bytes = payload
                .get(offset..offset + count * 4)
                .ok_or_else(|| content(format!("payload too short for array '{name}'")))?;
            let data = bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
            offset += count * 4;
            arrays.push(Array { name: name.to_string(), shape, data });
        }
        if offset != payload.len() {
            return Err(content(format!("payload has {} bytes, arrays describe {offset}", payload.len())));
        }
        Ok(Self { header, arrays })
    }
}

/// The header and payload lengths of a frame's 8-byte prefix, checked against the limits (`payload_limit`
/// at most `MAX_PAYLOAD_BYTES`).
fn frame_lengths(prefix: &[u8], payload_limit: usize) -> Result<(usize, usize), ProtocolError> {
    let length = |at: usize| u32::from_le_bytes([prefix[at], prefix[at + 1], prefix[at + 2], prefix[at + 3]]) as usize;
    let (header_len, payload_len) = (length(0), length(4));
    if header_len == 0 || header_len > MAX_HEADER_BYTES {
        return Err(ProtocolError::Framing(format!("header length {header_len} outside 1..={MAX_HEADER_BYTES}")));
    }
    if payload_len > payload_limit {
        return Err(ProtocolError::Framing(format!(
            "payload length {payload_len} is over this connection's limit of {payload_limit} bytes"
        )));
    }
    if payload_len % 4 != 0 {
        return Err(ProtocolError::Framing(format!(
            "payload length {payload_len} is not a multiple of 4 (the payload is f32 values)"
        )));
    }
    Ok((header_len, payload_len))
}

/// Collects a stream's bytes as they arrive and cuts them into messages, so that a server never blocks on a
/// peer that sent half a frame. It holds only the bytes received: once a large message is taken, the memory it
/// took goes back (`held_bytes` counts what is kept, not what is in use).
#[derive(Debug)]
pub struct FrameReader {
    buffer: Vec<u8>,
    payload_limit: usize,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self { buffer: Vec::new(), payload_limit: MAX_PAYLOAD_BYTES }
    }
}

impl FrameReader {
    /// A reader that refuses payloads over `payload_limit` bytes (at most `MAX_PAYLOAD_BYTES`).
    pub fn with_payload_limit(payload_limit: usize) -> Self {
        Self { buffer: Vec::new(), payload_limit: payload_limit.min(MAX_PAYLOAD_BYTES) }
    }

    /// Changes the payload limit for the frames still to come (at most `MAX_PAYLOAD_BYTES`).
    pub fn set_payload_limit(&mut self, payload_limit: usize) {
        self.payload_limit = payload_limit.min(MAX_PAYLOAD_BYTES);
    }

    /// Bytes received and not yet taken as messages (a half-sent frame's, for one).
    pub fn buffered_bytes(&self) -> usize {
        self.buffer.len()
    }

    /// Memory the reader keeps, bytes: its buffer's capacity, at least what is buffered.
    pub fn held_bytes(&self) -> usize {
        self.buffer.capacity()
    }

    /// One `read` of at most `max_bytes` from `reader`, straight into the buffer (call it when the stream is
    /// readable, so that it does not block). `Ok(0)` is the end of the stream.
    pub fn read_available(&mut self, reader: &mut impl Read, max_bytes: usize) -> std::io::Result<usize> {
        let start = self.buffer.len();
        self.buffer.resize(start + max_bytes, 0);
        let result = reader.read(&mut self.buffer[start..]);
        self.buffer.truncate(start + result.as_ref().map_or(0, |n| *n));
        result
    }

    /// The next complete message, if one has arrived. A `Framing` error means the stream cannot be
    /// resynchronised; a `Content` error consumed its frame and the stream goes on.
    pub fn next_message(&mut self) -> Option<Result<Message, ProtocolError>> {
        let (header_len, payload_len) = match frame_lengths(self.buffer.get(..8)?, self.payload_limit) {
            Ok(lengths) => lengths,
            Err(error) => return Some(Err(error)),
        };
        let total = 8 + header_len + payload_len;
        if self.buffer.len() < total {
            return None;
        }
        let result = Message::decode_parts(&self.buffer[8..8 + header_len], &self.buffer[8 + header_len..total]);
        self.buffer.drain(..total);
        release_spare(&mut self.buffer);
        Some(result)
    }
}

/// Capacity a connection's buffer keeps between messages, bytes: enough for the usual requests and replies
/// of a training run, so that they are not reallocated each time.
pub const KEPT_BUFFER_BYTES: usize = 256 * 1024;

/// Gives back the memory of a buffer that holds far less than it took (after a large message), keeping at
/// least `KEPT_BUFFER_BYTES`.
pub fn release_spare(buffer: &mut Vec<u8>) {
    if buffer.capacity() > KEPT_BUFFER_BYTES && buffer.len() < buffer.capacity() / 4 {
        buffer.shrink_to(buffer.len().max(KEPT_BUFFER_BYTES));
    }
}

/// An error reply.
pub fn error_reply(message: &str) -> Message {
    Message::new("error").with("message", Value::String(message.into()))
}

fn read_exact_or_closed(reader: &mut impl Read, buffer: &mut [u8]) -> Result<(), ProtocolError> {
    let mut filled = 0;
    while filled < buffer.len() {
        match reader.read(&mut buffer[filled..]) {
            Ok(0) if filled == 0 => return Err(ProtocolError::Closed),
            Ok(0) => {
                return Err(ProtocolError::Framing("connection closed inside a message".into()));
            }
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(ProtocolError::Io(e)),
        }
    }
    Ok(())
}

/// Reads exactly `len` bytes, growing the buffer as they arrive: a declared length costs memory only once
/// the bytes are really there (a peer cannot make us allocate 256 MiB with an 8-byte frame).
fn read_growing(reader: &mut impl Read, len: usize) -> Result<Vec<u8>, ProtocolError> {
    const CHUNK_BYTES: usize = 1 << 20;
    let mut buffer = Vec::with_capacity(len.min(CHUNK_BYTES));
    while buffer.len() < len {
        let start = buffer.len();
        buffer.resize((start + CHUNK_BYTES).min(len), 0);
        reader.read_exact(&mut buffer[start..]).map_err(truncated)?;
    }
    Ok(buffer)
}

fn truncated(error: std::io::Error) -> ProtocolError {
    if error.kind() == std::io::ErrorKind::UnexpectedEof {
        ProtocolError::Framing("connection closed inside a message".into())
    } else {
        ProtocolError::Io(error)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Message {
        Message::new("step")
            .with("slot_count", json!(2))
            .with_array(Array::new("actions", vec![2, 3], vec![0.5, -1.0, 0.25, 1.0, 0.0, -0.5]))
            .with_array(Array::new("empty", vec![0, 3], vec![]))
    }

    #[test]
    fn a_reader_gives_back_the_memory_of_a_large_message_once_it_is_taken() {
        let big = Message::new("step").with_array(Array::new("actions", vec![2_000_000], vec![0.5; 2_000_000]));
        let bytes = big.encode();
        let mut reader = FrameReader::default();
        let mut stream = &bytes[..];
        while reader.read_available(&mut stream, 64 * 1024).expect("reads") > 0 {}
        assert!(reader.held_bytes() >= bytes.len());
        assert!(matches!(reader.next_message(), Some(Ok(_))));
        assert!(reader.held_bytes() <= KEPT_BUFFER_BYTES, "kept {} bytes", reader.held_bytes());
    }

    #[test]
    fn round_trip() {
        let bytes = sample().encode();
        let decoded = Message::read_from(&mut bytes.as_slice()).expect("decodes");
        assert_eq!(decoded, sample());
        assert_eq!(decoded.message_type(), "step");
        assert_eq!(decoded.array("actions", &[2, 3]).expect("array").data[1], -1.0);
    }

    #[test]
    fn wrong_shapes_and_non_finite_values_are_content_errors() {
        let message = sample();
        assert!(matches!(message.array("actions", &[3, 2]), Err(ProtocolError::Content(_))));
        assert!(matches!(message.array("missing", &[1]), Err(ProtocolError::Content(_))));
        let nan = Message::new("step").with_array(Array::new("actions", vec![1], vec![f32::NAN]));
        assert!(matches!(nan.array("actions", &[1]), Err(ProtocolError::Content(_))));
    }

    #[test]
    fn huge_lengths_are_refused_before_allocating() {
        let mut bytes = Vec::new();
        bytes.extend_from_slice(&u32::MAX.to_le_bytes());
        bytes.extend_from_slice(&0u32.to_le_bytes());
        assert!(matches!(Message::read_from(&mut bytes.as_slice()), Err(ProtocolError::Framing(_))));
        let mut bytes = Vec::new();
        bytes.extend_from_slice(&10u32.to_le_bytes());
        bytes.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(Message::read_from(&mut bytes.as_slice()), Err(ProtocolError::Framing(_))));
    }

    #[test]
    fn truncated_and_empty_streams() {
        assert!(matches!(Message::read_from(&mut [].as_slice()), Err(ProtocolError::Closed)));
        let bytes = sample().encode();
        for cut in [3, 8, 20, bytes.len() - 1] {
            assert!(matches!(Message::read_from(&mut &bytes[..cut]), Err(ProtocolError::Framing(_))), "cut at {cut}");
        }
    }

    #[test]
    fn garbage_headers_are_content_errors() {
        for header in [
            &b"not json"[..],
            b"[1,2]",
            b"{}",
            br#"{"type": 3}"#,
            br#"{"type":"x","arrays":{}}"#,
            br#"{"type":"x","arrays":[{"name":"a","shape":[-1]}]}"#,
            br#"{"type":"x","arrays":[{"name":"a","shape":[4294967295,4294967295,16]}]}"#,
        ] {
            assert!(matches!(Message::decode_parts(header, &[]), Err(ProtocolError::Content(_))), "{header:?}");
        }
        // Payload longer than the arrays describe.
        assert!(matches!(Message::decode_parts(br#"{"type":"x"}"#, &[0; 4]), Err(ProtocolError::Content(_))));
    }

    #[test]
    fn random_bytes_never_panic() {
        // A small deterministic fuzz; the full property tests come with the hardening work.
        let mut state = 0x1234_5678_9abc_def0u64;
        for _ in 0..2000 {
            let mut bytes = Vec::new();
            let len = (state % 64) as usize;
            for _ in 0..len {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                bytes.push(state as u8);
            }
            let _ = Message::read_from(&mut bytes.as_slice());
        }
    }
}
