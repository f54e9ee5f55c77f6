//! Property tests of the wire format's decoder: whatever bytes arrive, decoding ends with a message or a
//! typed error, never a panic, a hang or an allocation the bytes did not pay for.

use std::io::Read;

use proptest::prelude::*;
use punch_core::training::protocol::{Array, FrameReader, MAX_PAYLOAD_BYTES, Message, ProtocolError};
use serde_json::json;

/// A reader that serves `bytes` and then reports the end of the stream.
struct Feed<'a> {
    bytes: &'a [u8],
}

impl Read for Feed<'_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let n = out.len().min(self.bytes.len());
        out[..n].copy_from_slice(&self.bytes[..n]);
        self.bytes = &self.bytes[n..];
        Ok(n)
    }
}

fn frame(header: &[u8], payload: &[u8]) -> Vec<u8> {
    let mut bytes = Vec::new();
    bytes.extend_from_slice(&(header.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    bytes.extend_from_slice(header);
    bytes.extend_from_slice(payload);
    bytes
}

fn message_strategy() -> impl Strategy<Value = Message> {
    let array = ("[a-z]{1,8}", prop::collection::vec(0usize..4, 0..3)).prop_flat_map(|(name, shape)| {
        let count: usize = shape.iter().product();
        prop::collection::vec(any::<f32>(), count).prop_map(move |data| Array::new(&name, shape.clone(), data))
    });
    ("[a-z_]{1,12}", any::<i64>(), prop::collection::vec(array, 0..4)).prop_map(|(kind, number, arrays)| {
        arrays.into_iter().fold(Message::new(&kind).with("n", json!(number)), Message::with_array)
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = Message::read_from(&mut Feed { bytes: &bytes });
    }

    #[test]
    fn random_headers_and_payloads_never_panic(header in prop::collection::vec(any::<u8>(), 1..256),
                                               payload in prop::collection::vec(any::<u8>(), 0..64)) {
        let payload = &payload[..payload.len() / 4 * 4];
        let _ = Message::read_from(&mut Feed { bytes: &frame(&header, payload) });
    }

    #[test]
    fn messages_round_trip(message in message_strategy()) {
        let bytes = message.encode();
        let decoded = Message::read_from(&mut Feed { bytes: &bytes }).expect("a valid message decodes");
        // NaN != NaN: compare the bit patterns of the arrays.
        prop_assert_eq!(decoded.message_type(), message.message_type());
        for (a, b) in decoded.arrays.iter().zip(&message.arrays) {
            prop_assert_eq!(&a.shape, &b.shape);
            prop_assert!(a.data.iter().zip(&b.data).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }

    #[test]
    fn every_truncation_is_a_framing_error(message in message_strategy(), cut in 0.0f64..1.0) {
        let bytes = message.encode();
        let cut = ((bytes.len() as f64 * cut) as usize).clamp(1, bytes.len() - 1);
        match Message::read_from(&mut Feed { bytes: &bytes[..cut] }) {
            Err(ProtocolError::Framing(_)) => {}
            other => prop_assert!(false, "cut at {cut} of {}: {other:?}", bytes.len()),
        }
    }

    #[test]
    fn declared_shapes_larger_than_the_payload_are_content_errors(
        shape in prop::collection::vec(any::<u64>(), 1..4), floats in 0usize..8) {
        let header = json!({"type": "step", "arrays": [{"name": "actions", "shape": shape}]}).to_string();
        let payload = vec![0u8; floats * 4];
        let count = shape.iter().try_fold(1u64, |acc, &d| acc.checked_mul(d));
        let result = Message::read_from(&mut Feed { bytes: &frame(header.as_bytes(), &payload) });
        if count == Some(floats as u64) {
            prop_assert!(result.is_ok());
        } else {
            prop_assert!(matches!(result, Err(ProtocolError::Content(_))), "{result:?}");
        }
    }

    #[test]
    fn non_finite_values_are_refused_where_actions_are_read(value in prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY)],
                                                           index in 0usize..6) {
        let mut data = vec![0.5f32; 6];
        data[index] = value;
        let message = Message::new("step").with_array(Array::new("actions", vec![2, 3], data));
        prop_assert!(message.array("actions", &[2, 3]).is_err());
    }
}

proptest! {
    #[test]
    fn frame_reader_cuts_any_chunking_of_a_stream_into_the_same_messages(
        messages in prop::collection::vec(message_strategy(), 1..4), chunk in 1usize..40) {
        let stream: Vec<u8> = messages.iter().flat_map(Message::encode).collect();
        let (mut reader, mut feed) = (FrameReader::default(), Feed { bytes: &stream });
        let mut decoded = Vec::new();
        while reader.read_available(&mut feed, chunk).expect("reads") > 0 {
            while let Some(result) = reader.next_message() {
                decoded.push(result.expect("valid frames"));
            }
        }
        prop_assert_eq!(decoded.len(), messages.len());
        for (a, b) in decoded.iter().zip(&messages) {
            prop_assert_eq!(a.encode(), b.encode());
        }
    }

    #[test]
    fn frame_reader_never_panics_on_random_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512), chunk in 1usize..64) {
        let (mut reader, mut feed) = (FrameReader::default(), Feed { bytes: &bytes });
        while reader.read_available(&mut feed, chunk).expect("reads") > 0 {
            while let Some(result) = reader.next_message() {
                if matches!(result, Err(ProtocolError::Framing(_))) {
                    return Ok(());
                }
            }
        }
    }
}

#[test]
fn a_huge_declared_payload_with_no_bytes_is_an_error_without_the_allocation() {
    let mut bytes = Vec::new();
    bytes.extend_from_slice(&16u32.to_le_bytes());
    bytes.extend_from_slice(&(MAX_PAYLOAD_BYTES as u32).to_le_bytes());
    bytes.extend_from_slice(br#"{"type":"step"}"#);
    bytes.push(b' ');
    // 256 MiB declared, 0 sent: the reader grows its buffer a chunk at a time and fails at the end of the stream.
    assert!(matches!(Message::read_from(&mut Feed { bytes: &bytes }), Err(ProtocolError::Framing(_))));
}
