//! The gRPC codec of the generated services: prost's, except that a message
//! is encoded into a buffer reserved at its exact encoded length, and decoded
//! from one contiguous slice.
//!
//! tonic's own encoder lets prost grow the buffer as it writes, doubling it:
//! a 10,000-pose `full` batch answer (~2.7 MB) then allocated and copied
//! ~5.4 MB, and the allocator kept the abandoned halves until its purge.
//! One `encoded_len` pass over the message is far cheaper than the copies.
//!
//! tonic hands the decoder a message already whole in one buffer, behind a
//! `DecodeBuf` whose every read goes through its length bookkeeping; prost
//! reads a plain `&[u8]` of the same bytes with its fast paths (varints,
//! fixed-width numbers). The same message and the same errors: a stream's
//! FK request (robot, six joints, options) took about 1,850 instructions to
//! decode through the `DecodeBuf` and about 1,250 from the slice (callgrind,
//! `kinserve`'s stream). The FK requests' joints are then merged into a
//! `Vec` with room for [`JOINTS_RESERVED`] values, where prost would grow it
//! from nothing twice for a 6-joint arm: about 960 in all.
//!
//! Depends on tonic, prost and two of the crate root's generated messages
//! (the FK requests, named only to give their joints room).

use std::marker::PhantomData;

use prost::bytes::Buf;
use prost::{DecodeError, Message};
use tonic::Status;
use tonic::codec::{BufferSettings, Codec, DecodeBuf, Decoder, EncodeBuf, Encoder};
use tonic_prost::ProstEncoder;

/// prost's codec with exact-size encoding (see the module documentation).
#[derive(Debug, Clone)]
pub struct ReservingCodec<T, U>(PhantomData<(T, U)>);

impl<T, U> Default for ReservingCodec<T, U> {
    fn default() -> Self {
        ReservingCodec(PhantomData)
    }
}

impl<T, U> Codec for ReservingCodec<T, U>
where
    T: Message + Send + 'static,
    U: Message + Default + Send + 'static,
{
    type Encode = T;
    type Decode = U;
    type Encoder = ReservingEncoder<T>;
    type Decoder = SliceDecoder<U>;

    fn encoder(&mut self) -> Self::Encoder {
        ReservingEncoder(ProstEncoder::new(BufferSettings::default()))
    }

    fn decoder(&mut self) -> Self::Decoder {
        SliceDecoder(PhantomData)
    }
}

/// prost's own encoder, after reserving the message's encoded length.
#[derive(Debug, Clone)]
pub struct ReservingEncoder<T>(ProstEncoder<T>);

impl<T: Message> Encoder for ReservingEncoder<T> {
    type Item = T;
    type Error = Status;

    fn encode(&mut self, item: T, buf: &mut EncodeBuf<'_>) -> Result<(), Status> {
        buf.reserve(item.encoded_len());
        self.0.encode(item, buf)
    }

    fn buffer_settings(&self) -> BufferSettings {
        self.0.buffer_settings()
    }
}

/// prost's decoding, from the message's bytes as one slice when they are
/// (always, with tonic's buffering), else in place.
#[derive(Debug, Clone)]
pub struct SliceDecoder<U>(PhantomData<U>);

impl<U: Message + Default + 'static> Decoder for SliceDecoder<U> {
    type Item = U;
    type Error = Status;

    fn decode(&mut self, buf: &mut DecodeBuf<'_>) -> Result<Option<U>, Status> {
        // As tonic-prost reports a message that does not decode.
        decode_from(buf)
            .map(Some)
            .map_err(|e| Status::internal(e.to_string()))
    }

    fn buffer_settings(&self) -> BufferSettings {
        BufferSettings::default()
    }
}

/// The message in `buf` (all of it): merged into [`empty`] from one slice
/// when the bytes are contiguous, in place otherwise (`Message::decode` is
/// `merge` into a default message: the same here, with room for the joints).
fn decode_from<U: Message + Default + 'static>(buf: &mut impl Buf) -> Result<U, DecodeError> {
    let mut item = empty::<U>();
    let len = buf.remaining();
    let whole = buf.chunk();
    if whole.len() == len {
        item.merge(whole)?;
        buf.advance(len);
    } else {
        item.merge(buf)?;
    }
    Ok(item)
}

/// Joint values the FK requests' `joints` have room for before decoding:
/// more than any serial arm of the built-in set (7), so a usual message
/// fills them without growing the `Vec`; a longer one grows as usual.
pub const JOINTS_RESERVED: usize = 8;

/// The default message of type `U`, its `joints` with room for
/// [`JOINTS_RESERVED`] values when `U` is an FK request (stream or unary).
fn empty<U: Default + 'static>() -> U {
    let mut item = U::default();
    let any: &mut dyn std::any::Any = &mut item;
    if let Some(m) = any.downcast_mut::<crate::pb::StreamForwardKinematicsRequest>() {
        m.joints.reserve_exact(JOINTS_RESERVED);
    } else if let Some(m) = any.downcast_mut::<crate::pb::ForwardKinematicsRequest>() {
        m.joints.reserve_exact(JOINTS_RESERVED);
    }
    item
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pb;

    /// Decodes `bytes` as one slice, and as two pieces (the in-place
    /// path); both must agree.
    fn decoded<U: Message + Default + PartialEq + std::fmt::Debug + 'static>(
        bytes: &[u8],
    ) -> Result<U, DecodeError> {
        let (a, b) = bytes.split_at(bytes.len() / 2);
        let mut pieces = a.chain(b);
        let in_place = decode_from::<U>(&mut pieces);
        let mut slice = bytes;
        let whole = decode_from::<U>(&mut slice);
        assert!(slice.is_empty() && !pieces.has_remaining() || whole.is_err());
        match (&whole, &in_place) {
            (Ok(x), Ok(y)) => assert_eq!(x, y),
            (Err(x), Err(y)) => assert_eq!(x.to_string(), y.to_string()),
            _ => panic!("{whole:?} vs {in_place:?}"),
        }
        whole
    }

    fn stream_request(joints: usize) -> pb::StreamForwardKinematicsRequest {
        pb::StreamForwardKinematicsRequest {
            id: 7,
            robot: "ur5e".into(),
            joints: (0..joints).map(|i| i as f64 * 0.1 - 0.3).collect(),
            options: Some(pb::FkOptions {
                angle_unit: 1,
                ..Default::default()
            }),
            ..Default::default()
        }
    }

    #[test]
    fn messages_decode_as_prost_decodes_them_and_joints_have_room() {
        for n in [0, 1, 6, 8, 9, 40] {
            let m = stream_request(n);
            let bytes = m.encode_to_vec();
            let got: pb::StreamForwardKinematicsRequest = decoded(&bytes).unwrap();
            assert_eq!(got, m, "{n} joints");
            assert!(got.joints.capacity() >= JOINTS_RESERVED.max(n));
            let unary = pb::ForwardKinematicsRequest {
                robot: m.robot.clone(),
                joints: m.joints.clone(),
                options: m.options,
            };
            let got: pb::ForwardKinematicsRequest = decoded(&unary.encode_to_vec()).unwrap();
            assert_eq!(got, unary);
            assert!(got.joints.capacity() >= JOINTS_RESERVED);
        }
        let health = pb::GetRobotRequest {
            name: "panda".into(),
        };
        let got: pb::GetRobotRequest = decoded(&health.encode_to_vec()).unwrap();
        assert_eq!(got, health);
    }

    #[test]
    fn a_broken_message_fails_as_prost_fails_it() {
        let bytes = stream_request(6).encode_to_vec();
        for cut in [1, bytes.len() / 2, bytes.len() - 1] {
            let part = &bytes[..cut];
            let want = pb::StreamForwardKinematicsRequest::decode(part).unwrap_err();
            let got = decoded::<pb::StreamForwardKinematicsRequest>(part).unwrap_err();
            assert_eq!(got.to_string(), want.to_string(), "cut at {cut}");
        }
    }
}
