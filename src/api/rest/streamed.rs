//! Large FK batch answers written as the connection takes them.
//!
//! A batch answer of [`STREAM_FROM_BYTES`] or more (by estimate) is not
//! serialised whole: the poses (96 bytes each) are kept and their JSON is
//! produced one frame of about [`FRAME_BYTES`] at a time, only when the
//! connection asks for the next frame. A client that reads nothing therefore
//! holds the computed poses and one frame (plus what hyper and the kernel
//! buffer), not a multi-megabyte JSON text; the bytes it holds are counted
//! against the response byte budget through [`Holds`] (the extension
//! [`super::buffered`] reads, defined there). The answer goes out
//! without `Content-Length` (HTTP/1.1 chunked, or HTTP/2 DATA frames), and
//! its bytes are exactly what serialising the whole [`FkBatchResponse`] gives.
//!
//! Large Cartesian paths ([`path_answer`]) stream the same way, row by row.
//!
//! Owns the JSON answer bodies of the REST handlers (whole, or streamed for
//! large batches and paths); which answers stream is decided here by size. Depends on
//! the DTOs, [`super::buffered`] (frame size, [`Holds`]),
//! [`crate::api::pose_format`] and [`crate::api::pose_json`] (the poses'
//! bytes), nothing above the adapter.

use std::pin::Pin;
use std::task::{Context, Poll};

use axum::body::{Body, Bytes, HttpBody};
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use http_body::{Frame, SizeHint};

use super::buffered::Holds;
use super::dto::FkBatchResponse;
use crate::api::ik::IkPathOutput;
use crate::api::pose_format::PoseFormat;
use crate::api::pose_json;
use crate::error::Error;
use crate::kinematics::Transform;

/// Largest frame of a streamed answer, in bytes: the response budget's frame
/// size, so frames are handed on whole.
pub const FRAME_BYTES: usize = super::buffered::FRAME_BYTES;

/// Room kept in a frame for one more pose (a `full` pose is at most about
/// 700 bytes), in bytes.
const POSE_ROOM: usize = 1024;

/// Answers estimated at this many bytes or more are streamed.
pub const STREAM_FROM_BYTES: usize = 64 << 10;

/// What a streamed answer may have produced and not yet seen written, in
/// bytes: hyper's HTTP/1 write buffer limit (its default `max_buf_size`,
/// 8 KiB + 100 × 4 KiB) and the frame being handed over.
const IN_FLIGHT_BYTES: usize = 8192 + 4096 * 100 + FRAME_BYTES;

/// A generous estimate of the JSON size of `n` poses in `format`, in bytes
/// (17 significant digits per number).
pub fn estimated_bytes(format: PoseFormat, n: usize) -> usize {
    let per_pose = match format {
        PoseFormat::Full => 720,
        PoseFormat::Matrix => 12 * 24,
        PoseFormat::Position => 3 * 24,
    };
    n.saturating_mul(per_pose)
}

/// Bytes reserved for a whole answer of `n` poses in `format` written at
/// once: [`estimated_bytes`] and the fields around the poses.
pub fn answer_capacity(format: PoseFormat, n: usize) -> usize {
    estimated_bytes(format, n).saturating_add(128)
}

/// The 200 answer to a batch: serialised at once when small, streamed (see
/// the module documentation) when [`estimated_bytes`] reaches
/// [`STREAM_FROM_BYTES`].
pub fn batch_answer(
    robot: &str,
    length_unit: crate::model::LengthUnit,
    format: PoseFormat,
    poses: Vec<Transform>,
) -> Result<Response, Error> {
    let empty = FkBatchResponse::new(robot, length_unit, format, &[]);
    let shell = json_bytes(&empty, 256)?;
    // The poses' field (`poses`, `matrices` or `positions`, by format) is the
    // last one written: the shell ends with `[]}`; the head keeps `[`. The
    // poses go between, written by `pose_json` (serde_json's bytes).
    let Some(head) = shell.as_slice().strip_suffix(b"]}".as_slice()) else {
        return Err(internal("the batch answer does not end with its poses"));
    };
    if estimated_bytes(format, poses.len()) < STREAM_FROM_BYTES {
        let whole = encoded(answer_capacity(format, poses.len()), |out| {
            out.extend_from_slice(head);
            pose_json::items(out, format, &poses);
            out.extend_from_slice(b"]}");
            Ok(())
        })?;
        return Ok(json_answer(whole));
    }
    let holds = poses.len() * std::mem::size_of::<Transform>() + IN_FLIGHT_BYTES;
    let body = ItemsBody::new(head, b"]}", poses, move |buf, pose: &Transform| {
        pose_json::pose(buf, format, pose);
        Ok(())
    });
    let mut resp = json_answer(Body::new(body));
    resp.extensions_mut().insert(Holds(holds));
    Ok(resp)
}

/// The 200 answer of a Cartesian path: serialised at once when small; when
/// its rows (17 significant digits per joint value) reach
/// [`STREAM_FROM_BYTES`], the rows of `points` are written a frame at a time
/// between the rest of the answer, as for batches. The bytes are exactly
/// what serialising the whole [`IkPathOutput`] gives.
pub fn path_answer(mut answer: IkPathOutput) -> Result<Response, Error> {
    let dof = answer.points.first().map_or(0, Vec::len);
    let estimate = answer.points.len().saturating_mul(24 * dof + 2);
    if estimate < STREAM_FROM_BYTES {
        return json_bytes(&answer, estimate + 256).map(json_answer);
    }
    let rows = std::mem::take(&mut answer.points);
    let shell = json_bytes(&answer, 512)?;
    // The shell holds `"points":[]` once: the rows go between its brackets.
    let marker = b"\"points\":[]";
    let Some(at) = shell.windows(marker.len()).position(|w| w == marker) else {
        return Err(internal("the path answer has no points field"));
    };
    let (head, tail) = shell.split_at(at + marker.len() - 1);
    let holds = rows.len() * (dof * 8 + std::mem::size_of::<Vec<f64>>()) + IN_FLIGHT_BYTES;
    let body = ItemsBody::new(head, tail, rows, |buf, row: &Vec<f64>| {
        serde_json::to_writer(buf, row)
    });
    let mut resp = json_answer(Body::new(body));
    resp.extensions_mut().insert(Holds(holds));
    Ok(resp)
}

fn internal(detail: &str) -> Error {
    Error::Internal {
        detail: detail.into(),
    }
}

/// `value` as JSON, in a buffer of `capacity` bytes to start with, under
/// the request's `encode` span.
pub(super) fn json_bytes<T: serde::Serialize>(
    value: &T,
    capacity: usize,
) -> Result<Vec<u8>, Error> {
    encoded(capacity, |out| serde_json::to_writer(out, value))
}

/// The bytes `write` appends to a buffer of `capacity` bytes to start with,
/// under the request's `encode` span.
pub(super) fn encoded(
    capacity: usize,
    write: impl FnOnce(&mut Vec<u8>) -> serde_json::Result<()>,
) -> Result<Vec<u8>, Error> {
    let _encode = crate::trace_span!("encode").entered();
    let mut bytes = Vec::with_capacity(capacity);
    write(&mut bytes).map_err(|e| internal(&e.to_string()))?;
    Ok(bytes)
}

/// `value` as JSON in a buffer of `capacity` bytes to start with (no span:
/// the WebSocket's messages have none of their own).
pub(super) fn json_vec<T: serde::Serialize>(
    value: &T,
    capacity: usize,
) -> serde_json::Result<Vec<u8>> {
    let mut bytes = Vec::with_capacity(capacity);
    serde_json::to_writer(&mut bytes, value)?;
    Ok(bytes)
}

/// A 200 `application/json` answer with `body`.
pub(super) fn json_answer(body: impl Into<Body>) -> Response {
    (
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        )],
        body.into(),
    )
        .into_response()
}

/// The body of a streamed answer: its head (`{…,"poses":[`, `"matrices":[`,
/// `"positions":[` or `{…,"points":[`), then the items a frame at a time,
/// each written by `write`, then its tail (`]}`, or `],"fraction":…}`).
struct ItemsBody<T, W> {
    head: Option<Bytes>,
    tail: Bytes,
    items: Vec<T>,
    write: W,
    next: usize,
    done: bool,
}

impl<T, W> ItemsBody<T, W>
where
    W: FnMut(&mut Vec<u8>, &T) -> Result<(), serde_json::Error>,
{
    fn new(head: &[u8], tail: &[u8], items: Vec<T>, write: W) -> Self {
        ItemsBody {
            head: Some(Bytes::copy_from_slice(head)),
            tail: Bytes::copy_from_slice(tail),
            items,
            write,
            next: 0,
            done: false,
        }
    }

    /// The next frame: the head (first time), items up to [`FRAME_BYTES`],
    /// and the tail after the last item.
    fn frame(&mut self) -> Result<Bytes, serde_json::Error> {
        let mut buf = Vec::with_capacity(FRAME_BYTES);
        if let Some(head) = self.head.take() {
            buf.extend_from_slice(&head);
        }
        while buf.len() + POSE_ROOM <= FRAME_BYTES {
            let Some(item) = self.items.get(self.next) else {
                break;
            };
            if self.next > 0 {
                buf.push(b',');
            }
            (self.write)(&mut buf, item)?;
            self.next += 1;
        }
        if self.next >= self.items.len() {
            buf.extend_from_slice(&self.tail);
            self.done = true;
            self.items = Vec::new();
        }
        Ok(Bytes::from(buf))
    }
}

impl<T: Unpin, W> HttpBody for ItemsBody<T, W>
where
    W: FnMut(&mut Vec<u8>, &T) -> Result<(), serde_json::Error> + Unpin,
{
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        _cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        let this = self.get_mut();
        if this.done {
            return Poll::Ready(None);
        }
        Poll::Ready(Some(
            this.frame().map(Frame::data).map_err(axum::Error::new),
        ))
    }

    fn is_end_stream(&self) -> bool {
        self.done
    }

    fn size_hint(&self) -> SizeHint {
        // At least the tail and two bytes per item left: never an exact
        // length, so no `Content-Length` is sent.
        let left = self.items.len().saturating_sub(self.next) as u64;
        let mut hint = SizeHint::new();
        hint.set_lower(if self.done {
            0
        } else {
            self.tail.len() as u64 + 2 * left
        });
        hint
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::LengthUnit;

    fn poses(n: usize) -> Vec<Transform> {
        (0..n)
            .map(|i| {
                let x = i as f64 * 1e-3;
                Transform::rot_z(0.1 + x).compose(&Transform::translation(x, 0.3 - x, 1.0 / 3.0))
            })
            .collect()
    }

    fn whole(format: PoseFormat, poses: &[Transform]) -> Vec<u8> {
        serde_json::to_vec(&FkBatchResponse::new(
            "puma560",
            LengthUnit::M,
            format,
            poses,
        ))
        .unwrap()
    }

    async fn collected(resp: Response) -> (Option<Holds>, Vec<Vec<u8>>) {
        let holds = resp.extensions().get::<Holds>().copied();
        let mut body = resp.into_body();
        let mut frames = Vec::new();
        while let Some(f) = http_body_util::BodyExt::frame(&mut body).await {
            frames.push(f.unwrap().into_data().unwrap().to_vec());
        }
        (holds, frames)
    }

    #[tokio::test]
    async fn a_streamed_answer_is_the_whole_answer_byte_for_byte() {
        for format in [PoseFormat::Full, PoseFormat::Matrix, PoseFormat::Position] {
            for n in [0, 1, 2, 99, 1000, 2345] {
                let ps = poses(n);
                let want = whole(format, &ps);
                let resp = batch_answer("puma560", LengthUnit::M, format, ps).unwrap();
                let streamed = estimated_bytes(format, n) >= STREAM_FROM_BYTES;
                assert_eq!(resp.body().size_hint().exact().is_none(), streamed);
                let (holds, frames) = collected(resp).await;
                assert_eq!(holds.is_some(), streamed, "{format:?} × {n}");
                let got: Vec<u8> = frames.iter().flatten().copied().collect();
                assert!(
                    got == want,
                    "{format:?} × {n}: {} bytes streamed, {} whole",
                    got.len(),
                    want.len()
                );
                if streamed && want.len() > FRAME_BYTES {
                    assert!(frames.len() > 1, "{format:?} × {n}: one frame");
                    for f in &frames {
                        assert!(f.len() <= FRAME_BYTES, "frame of {} bytes", f.len());
                    }
                }
            }
        }
    }

    fn path(n: usize, stop: bool) -> IkPathOutput {
        let points = (0..n)
            .map(|i| (0..7).map(|j| (i * 7 + j) as f64 / 3.0 - 1.0).collect())
            .collect();
        let stop = stop.then(|| crate::model::PathStop {
            step: n,
            waypoint: 1,
            reason: crate::model::PathStopReason::JointJump,
            detail: "joint 4 would move 0.9 rad".into(),
        });
        IkPathOutput {
            robot: "panda".into(),
            length_unit: LengthUnit::M,
            angle_unit: crate::model::AngleUnit::Rad,
            points,
            fraction: 0.5,
            waypoints_reached: 1,
            stop,
        }
    }

    #[tokio::test]
    async fn a_streamed_path_is_the_whole_path_byte_for_byte() {
        for n in [0, 1, 50, 400, 3000] {
            for stop in [false, true] {
                let answer = path(n, stop);
                let want = serde_json::to_vec(&answer).unwrap();
                let resp = path_answer(answer).unwrap();
                let streamed = resp.body().size_hint().exact().is_none();
                assert_eq!(streamed, n * (24 * 7 + 2) >= STREAM_FROM_BYTES, "{n}");
                let (holds, frames) = collected(resp).await;
                assert_eq!(holds.is_some(), streamed, "{n}");
                let got: Vec<u8> = frames.iter().flatten().copied().collect();
                assert!(
                    got == want,
                    "{n} rows: {} bytes vs {}",
                    got.len(),
                    want.len()
                );
                if streamed && want.len() > FRAME_BYTES {
                    assert!(frames.len() > 1, "{n} rows in one frame");
                    assert!(frames.iter().all(|f| f.len() <= FRAME_BYTES));
                }
            }
        }
    }

    #[test]
    fn the_estimate_is_not_below_the_real_size_of_full_poses() {
        let ps = poses(500);
        for format in [PoseFormat::Full, PoseFormat::Matrix, PoseFormat::Position] {
            let real = whole(format, &ps).len();
            assert!(estimated_bytes(format, 500) >= real, "{format:?}: {real}");
        }
    }
}
