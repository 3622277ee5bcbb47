//! The three protobuf messages that carry a batch's numbers, written by hand
//! in place of prost's generated code (`extern_path` in `build.rs`;
//! re-exported as `pb::JointConfiguration`, `pb::PackedConfigurations` and
//! `pb::PackedPoses`): the same wire format and the same Rust fields, but
//! their packed `double` fields are read and written in bulk.
//!
//! prost decodes a packed field one value at a time (a bounds check, a read
//! and a `Vec::push` that grows the vector by doubling) and encodes it the
//! same way. A 10,000-configuration gRPC batch is 10,000 `JointConfiguration`
//! messages in and, in a compact format, one `PackedPoses` of 120,000 numbers
//! out: that per-value work was about a quarter of the server's time on such
//! a batch, and more of a Rust client's. Here a packed field reserves its
//! length once and is copied from (or into) the buffer a contiguous piece at
//! a time.
//!
//! Every other case — a field sent unpacked, a length that is not a whole
//! number of doubles or runs past the message, an unknown field — goes
//! through prost's own functions, so errors and merging rules are prost's
//! (tests decode and encode against prost-derived twins of the messages).
//!
//! Depends on prost and bytes only (not on [`crate::pb`], which depends on it).

use prost::bytes::{Buf, BufMut};
use prost::encoding::{self, DecodeContext, WireType};
use prost::{DecodeError, Message};

/// One joint configuration (`kinematics.v1.JointConfiguration`).
#[derive(Clone, PartialEq, Default, Debug)]
pub struct JointConfiguration {
    /// Joint values (see `ForwardKinematicsRequest.joints`), field 1.
    pub joints: Vec<f64>,
}

/// Poses packed into one field (`kinematics.v1.PackedPoses`).
#[derive(Clone, PartialEq, Default, Debug)]
pub struct PackedPoses {
    /// The format of `values` (a `PoseFormat` number: `POSE_FORMAT_MATRIX`
    /// or `POSE_FORMAT_POSITION`), field 1.
    pub format: i32,
    /// `k` numbers per pose, pose after pose, field 2.
    pub values: Vec<f64>,
}

/// Joint configurations packed into one field
/// (`kinematics.v1.PackedConfigurations`).
#[derive(Clone, PartialEq, Default, Debug)]
pub struct PackedConfigurations {
    /// Values per configuration (the robot's joint count), field 1.
    pub joint_count: u32,
    /// `joint_count` values per configuration, configuration after
    /// configuration, field 2.
    pub values: Vec<f64>,
}

impl Message for JointConfiguration {
    fn encode_raw(&self, buf: &mut impl BufMut) {
        put_packed(1, &self.joints, buf);
    }

    fn merge_field(
        &mut self,
        tag: u32,
        wire_type: WireType,
        buf: &mut impl Buf,
        ctx: DecodeContext,
    ) -> Result<(), DecodeError> {
        match tag {
            1 => in_field(
                merge_packed(wire_type, &mut self.joints, buf, ctx),
                "JointConfiguration",
                "joints",
            ),
            _ => encoding::skip_field(wire_type, tag, buf, ctx),
        }
    }

    fn encoded_len(&self) -> usize {
        encoding::double::encoded_len_packed(1, &self.joints)
    }

    fn clear(&mut self) {
        self.joints.clear();
    }
}

/// `Message` for a message of one scalar field 1 (`$field`, of prost's
/// encoding `$codec`, omitted when 0) and the packed `double` field 2
/// (`values`): `PackedPoses` and `PackedConfigurations`.
macro_rules! scalar_and_values {
    ($name:ident, $field:ident, $codec:ident) => {
        impl Message for $name {
            fn encode_raw(&self, buf: &mut impl BufMut) {
                if self.$field != 0 {
                    encoding::$codec::encode(1, &self.$field, buf);
                }
                put_packed(2, &self.values, buf);
            }

            fn merge_field(
                &mut self,
                tag: u32,
                wire_type: WireType,
                buf: &mut impl Buf,
                ctx: DecodeContext,
            ) -> Result<(), DecodeError> {
                let message = stringify!($name);
                match tag {
                    1 => in_field(
                        encoding::$codec::merge(wire_type, &mut self.$field, buf, ctx),
                        message,
                        stringify!($field),
                    ),
                    2 => in_field(
                        merge_packed(wire_type, &mut self.values, buf, ctx),
                        message,
                        "values",
                    ),
                    _ => encoding::skip_field(wire_type, tag, buf, ctx),
                }
            }

            fn encoded_len(&self) -> usize {
                let head = if self.$field != 0 {
                    encoding::$codec::encoded_len(1, &self.$field)
                } else {
                    0
                };
                head + encoding::double::encoded_len_packed(2, &self.values)
            }

            fn clear(&mut self) {
                self.$field = 0;
                self.values.clear();
            }
        }
    };
}

scalar_and_values!(PackedPoses, format, int32);
scalar_and_values!(PackedConfigurations, joint_count, uint32);

/// `result` with its error, if any, marked as found in `message.field` (what
/// prost's derived code adds to an error).
fn in_field(
    result: Result<(), DecodeError>,
    message: &'static str,
    field: &'static str,
) -> Result<(), DecodeError> {
    result.map_err(|mut e| {
        e.push(message, field);
        e
    })
}

/// Bytes per value.
const WIDTH: usize = 8;

/// Values converted per `put_slice` when encoding.
const BLOCK: usize = 64;

/// Writes `values` as the packed field `tag` (nothing when empty, as prost).
fn put_packed(tag: u32, values: &[f64], buf: &mut impl BufMut) {
    if values.is_empty() {
        return;
    }
    encoding::encode_key(tag, WireType::LengthDelimited, buf);
    encoding::encode_varint((values.len() * WIDTH) as u64, buf);
    let mut block = [[0u8; WIDTH]; BLOCK];
    for part in values.chunks(BLOCK) {
        for (dst, v) in block.iter_mut().zip(part) {
            *dst = v.to_le_bytes();
        }
        let filled = block.get(..part.len()).unwrap_or_default();
        buf.put_slice(filled.as_flattened());
    }
}

/// Merges one occurrence of a repeated `double` field into `values`: a
/// packed one in bulk, anything else (unpacked, malformed) by prost.
fn merge_packed(
    wire_type: WireType,
    values: &mut Vec<f64>,
    buf: &mut impl Buf,
    ctx: DecodeContext,
) -> Result<(), DecodeError> {
    if wire_type != WireType::LengthDelimited {
        return encoding::double::merge_repeated(wire_type, values, buf, ctx);
    }
    let len = encoding::decode_varint(buf)?;
    let whole = usize::try_from(len)
        .ok()
        .filter(|&n| n <= buf.remaining() && n % WIDTH == 0);
    let Some(bytes) = whole else {
        // prost's own path (and error) for a length it would refuse: the
        // length read above is handed back in front of the rest.
        let mut head = Vec::with_capacity(10);
        encoding::encode_varint(len, &mut head);
        let mut again = head.as_slice().chain(buf);
        return encoding::double::merge_repeated(wire_type, values, &mut again, ctx);
    };
    let mut left = bytes / WIDTH;
    values.reserve(left);
    while left > 0 {
        let (pieces, _) = buf.chunk().as_chunks::<WIDTH>();
        let take = pieces.len().min(left);
        if take == 0 {
            // A value split between two pieces of the buffer.
            values.push(buf.get_f64_le());
            left -= 1;
            continue;
        }
        let pieces = pieces.get(..take).unwrap_or_default();
        values.extend(pieces.iter().map(|b| f64::from_le_bytes(*b)));
        buf.advance(take * WIDTH);
        left -= take;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use prost::bytes::Bytes;

    use super::*;

    /// prost-derived twins of both messages: what the generated code did.
    #[derive(Clone, PartialEq, prost::Message)]
    struct ProstJointConfiguration {
        #[prost(double, repeated, tag = "1")]
        joints: Vec<f64>,
    }

    #[derive(Clone, PartialEq, prost::Message)]
    struct ProstPackedPoses {
        #[prost(int32, tag = "1")]
        format: i32,
        #[prost(double, repeated, tag = "2")]
        values: Vec<f64>,
    }

    #[derive(Clone, PartialEq, prost::Message)]
    struct ProstPackedConfigurations {
        #[prost(uint32, tag = "1")]
        joint_count: u32,
        #[prost(double, repeated, tag = "2")]
        values: Vec<f64>,
    }

    /// Values of every kind a double can be, `n` of them.
    fn values(n: usize, seed: u64) -> Vec<f64> {
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.5e-300,
            f64::MAX,
            f64::MIN_POSITIVE,
            1e-310,
        ];
        let mut s = seed | 1;
        (0..n)
            .map(|k| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                match special.get(k % 11) {
                    Some(v) => *v,
                    None => f64::from_bits(s) % 1e6,
                }
            })
            .collect()
    }

    /// Whether `a` and `b` hold the same values bit for bit.
    fn same_bits(a: &[f64], b: &[f64]) -> bool {
        a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    /// A buffer of two pieces, split at `at`: values straddle the seam.
    fn split(bytes: &[u8], at: usize) -> impl Buf {
        let at = at.min(bytes.len());
        Bytes::copy_from_slice(&bytes[..at]).chain(Bytes::copy_from_slice(&bytes[at..]))
    }

    #[test]
    fn encodings_are_prost_byte_for_byte() {
        for n in [0, 1, 6, 7, 63, 64, 65, 129, 1000] {
            let v = values(n, n as u64 + 3);
            let ours = JointConfiguration { joints: v.clone() };
            let theirs = ProstJointConfiguration { joints: v.clone() };
            assert_eq!(ours.encode_to_vec(), theirs.encode_to_vec(), "{n} joints");
            assert_eq!(ours.encoded_len(), theirs.encoded_len());
            for format in [0, 2, 3, -1] {
                let ours = PackedPoses {
                    format,
                    values: v.clone(),
                };
                let theirs = ProstPackedPoses {
                    format,
                    values: v.clone(),
                };
                assert_eq!(
                    ours.encode_to_vec(),
                    theirs.encode_to_vec(),
                    "{n} values, format {format}"
                );
                assert_eq!(ours.encoded_len(), theirs.encoded_len());
            }
            for joint_count in [0, 6, 300] {
                let ours = PackedConfigurations {
                    joint_count,
                    values: v.clone(),
                };
                let theirs = ProstPackedConfigurations {
                    joint_count,
                    values: v.clone(),
                };
                assert_eq!(ours.encode_to_vec(), theirs.encode_to_vec());
                assert_eq!(ours.encoded_len(), theirs.encoded_len());
            }
        }
    }

    #[test]
    fn decodings_equal_prost_s_on_contiguous_and_split_buffers() {
        for n in [0, 1, 6, 65, 300] {
            let v = values(n, 11 * n as u64 + 1);
            let bytes = ProstPackedPoses {
                format: 2,
                values: v.clone(),
            }
            .encode_to_vec();
            for at in [0, 1, 3, 8, 13, bytes.len() / 2, bytes.len()] {
                let ours = PackedPoses::decode(split(&bytes, at)).unwrap();
                assert_eq!(ours.format, 2);
                assert_eq!(ours.values.len(), n);
                // Bit for bit (-0.0 and subnormals included).
                assert!(
                    ours.values
                        .iter()
                        .zip(&v)
                        .all(|(a, b)| a.to_bits() == b.to_bits())
                );
            }
            let bytes = ProstPackedConfigurations {
                joint_count: 7,
                values: v.clone(),
            }
            .encode_to_vec();
            for at in [1, 2, 9, bytes.len() / 2] {
                let ours = PackedConfigurations::decode(split(&bytes, at)).unwrap();
                assert_eq!(ours.joint_count, 7);
                assert!(ours.values.len() == n && same_bits(&ours.values, &v));
            }
            let bytes = ProstJointConfiguration { joints: v.clone() }.encode_to_vec();
            let ours = JointConfiguration::decode(split(&bytes, 5)).unwrap();
            assert!(
                ours.joints
                    .iter()
                    .zip(&v)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
        }
    }

    #[test]
    fn unpacked_repeated_and_unknown_fields_merge_as_prost_merges_them() {
        // Field 1 unpacked (fixed64 each), then packed, then unpacked again,
        // with an unknown varint field 9 in between: all values, in order.
        let mut bytes = Vec::new();
        for v in [1.5, -2.0] {
            encoding::double::encode(1, &v, &mut bytes);
        }
        encoding::uint64::encode(9, &77, &mut bytes);
        encoding::double::encode_packed(1, &[3.0, 4.0], &mut bytes);
        encoding::double::encode(1, &5.0, &mut bytes);
        let theirs = ProstJointConfiguration::decode(bytes.as_slice()).unwrap();
        let ours = JointConfiguration::decode(bytes.as_slice()).unwrap();
        assert_eq!(ours.joints, theirs.joints);
        assert_eq!(ours.joints, [1.5, -2.0, 3.0, 4.0, 5.0]);
    }

    #[test]
    fn malformed_packed_fields_are_refused_as_prost_refuses_them() {
        let good = ProstJointConfiguration {
            joints: vec![1.0, 2.0],
        }
        .encode_to_vec();
        // [key, len = 16, 16 bytes]: a length 1 too short or too long.
        let mut cases: Vec<Vec<u8>> = Vec::new();
        for len in [15u8, 17, 9, 200] {
            let mut b = good.clone();
            b[1] = len;
            cases.push(b);
        }
        cases.push(good[..good.len() - 3].to_vec()); // truncated
        cases.push(vec![0x0a]); // key without a length
        cases.push(vec![
            0x0a, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01,
        ]);
        for (k, bytes) in cases.iter().enumerate() {
            let theirs = ProstJointConfiguration::decode(bytes.as_slice());
            let ours = JointConfiguration::decode(bytes.as_slice());
            assert!(theirs.is_err(), "case {k}: prost accepts it");
            assert!(ours.is_err(), "case {k}: accepted {ours:?}");
            let (ours, theirs) = (
                ours.unwrap_err().to_string(),
                theirs.unwrap_err().to_string(),
            );
            // Same cause; ours names the message and field it was in.
            let cause = theirs.rsplit(": ").next().unwrap_or_default();
            assert!(ours.contains(cause), "case {k}: {ours} vs {theirs}");
        }
    }
}
