//! The gRPC codec of the generated services: prost's, except that a message
//! is encoded into a buffer reserved at its exact encoded length.
//!
//! tonic's own encoder lets prost grow the buffer as it writes, doubling it:
//! a 10,000-pose `full` batch answer (~2.7 MB) then allocated and copied
//! ~5.4 MB, and the allocator kept the abandoned halves until its purge.
//! One `encoded_len` pass over the message is far cheaper than the copies.
//!
//! Depends on tonic and prost only.

use std::marker::PhantomData;

use prost::Message;
use tonic::Status;
use tonic::codec::{BufferSettings, Codec, EncodeBuf, Encoder};
use tonic_prost::{ProstDecoder, ProstEncoder};

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
    type Decoder = ProstDecoder<U>;

    fn encoder(&mut self) -> Self::Encoder {
        ReservingEncoder(ProstEncoder::new(BufferSettings::default()))
    }

    fn decoder(&mut self) -> Self::Decoder {
        ProstDecoder::new(BufferSettings::default())
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
