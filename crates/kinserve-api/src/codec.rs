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
//! `kinserve`'s stream; most of what is left is prost growing the joints'
//! `Vec` one value at a time and the robot name's `String`).
//!
//! Depends on tonic and prost only.

use std::marker::PhantomData;

use prost::Message;
use prost::bytes::Buf;
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

impl<U: Message + Default> Decoder for SliceDecoder<U> {
    type Item = U;
    type Error = Status;

    fn decode(&mut self, buf: &mut DecodeBuf<'_>) -> Result<Option<U>, Status> {
        let len = buf.remaining();
        let whole = buf.chunk();
        let item = if whole.len() == len {
            let item = U::decode(whole);
            buf.advance(len);
            item
        } else {
            U::decode(buf)
        };
        // As tonic-prost reports a message that does not decode.
        item.map(Some).map_err(|e| Status::internal(e.to_string()))
    }

    fn buffer_settings(&self) -> BufferSettings {
        BufferSettings::default()
    }
}
