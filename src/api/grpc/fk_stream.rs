//! A `StreamForwardKinematics` call: the response stream that reads the
//! client's messages in order and answers each one when tonic asks for the
//! next reply, how the call ends (the client's end, idle timeout, shutdown,
//! a bad message), and the watchdog that frees a call whose client stopped
//! taking replies.
//!
//! The replies are produced on the task that sends them (tonic polls
//! [`FkReplies`] for the next reply; FK of one configuration is answered in
//! that poll), so a message costs no hand-over between tasks and no reply
//! queue: tonic encodes replies as they come and hands the HTTP/2 layer its
//! buffer when the replies stop coming or it is full. Back-pressure is the
//! HTTP/2 flow control itself: while the client's receive window is closed,
//! the HTTP/2 layer stops asking for replies, so no message is read.
//!
//! That is also why a call needs a watchdog: a call blocked on the client's
//! window is not polled at all, so it cannot time itself out. The watchdog
//! ([`watch`]) holds the call's stream slot; when the call has been owed a
//! poll for the idle timeout, it gives the slot back, makes a later poll
//! end the call `DEADLINE_EXCEEDED`, and closes the connection if the call
//! is still not done after [`streams::STUCK_GRACE`] (see `streams`: the
//! HTTP/2 layer cannot end that one stream while it waits for window).
//!
//! Depends on `stream` (the answers), `streams` (connection info, the grace
//! period), `oversize` and the budgets.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::task::{Context, Poll, ready};
use std::time::Duration;

use tokio::time::{Instant, Sleep};
use tokio_stream::Stream;
use tokio_util::sync::{CancellationToken, DropGuard, WaitForCancellationFutureOwned};
use tonic::{Status, Streaming};

use super::stream::{Answer, LaterReply};
use super::{GrpcService, oversize, pb, streams};
use crate::api::budget::StreamPermit;
use crate::compute::ClientId;
use crate::error::Error;
use crate::service::RobotCache;
use crate::telemetry::StreamGuard;

/// The replies of one `StreamForwardKinematics` call, in the order of its
/// messages, then the call's end: `None` once the client has ended its
/// side and every message is answered; a status for an idle timeout
/// (`DEADLINE_EXCEEDED`), a server shutdown (`UNAVAILABLE`), a message that
/// cannot be decoded or is too large, or a bug (`INTERNAL`).
pub struct FkReplies {
    grpc: GrpcService,
    inbound: Streaming<pb::StreamForwardKinematicsRequest>,
    client: ClientId,
    robots: RobotCache,
    /// The message being answered on the compute pool: no further message
    /// is read until its reply is out.
    later: Option<LaterReply>,
    /// When waiting for the client's next message: the deadline.
    idle: Pin<Box<Sleep>>,
    /// Whether `idle` is armed for the current wait.
    waiting: bool,
    /// How long a wait for a message may last: the first-message timeout
    /// until the first message, then the idle timeout.
    wait: Duration,
    idle_timeout: Duration,
    /// The call's own token, cancelled with the server's: checking it per
    /// message locks only this call's node, where the server's token is one
    /// mutex every call of every worker would take.
    shutdown: CancellationToken,
    shutting_down: Pin<Box<WaitForCancellationFutureOwned>>,
    polls: u64,
    watched: Arc<Watched>,
    ended: bool,
    /// Tells the watchdog the call is done when the HTTP layer drops it.
    _done: DropGuard,
}

/// What the call shows its watchdog.
#[derive(Default)]
struct Watched {
    /// Polls so far (shifted left by one), and in the low bit whether the
    /// call is owed a poll within its limit: always, except while it waits
    /// for the compute pool (whose operations have their own bounds). A call
    /// that waits for a message is polled by the message or by its own
    /// deadline, unless the HTTP layer waits for the client's window.
    polls: AtomicU64,
    /// Set by the watchdog: the call was closed for idleness.
    closed: AtomicBool,
}

impl GrpcService {
    /// The replies of a call on `inbound` from `client`, holding `held`
    /// (its stream slot and gauge) until the call is done or given up.
    pub(super) fn fk_replies(
        &self,
        inbound: Streaming<pb::StreamForwardKinematicsRequest>,
        client: ClientId,
        held: (StreamPermit, StreamGuard),
        connection: Option<streams::GrpcConnInfo>,
    ) -> FkReplies {
        let idle_timeout = self.settings.stream_idle_timeout;
        let limits = Limits {
            first: idle_timeout.min(self.settings.stream_first_message_timeout),
            idle: idle_timeout,
        };
        let shutdown = self.shutdown.child_token();
        let done = CancellationToken::new();
        let watched = Arc::new(Watched {
            polls: AtomicU64::new(1),
            closed: AtomicBool::new(false),
        });
        tokio::spawn(watch(
            Arc::clone(&watched),
            done.clone(),
            shutdown.clone(),
            limits,
            held,
            connection,
        ));
        FkReplies {
            grpc: self.clone(),
            inbound,
            client,
            robots: RobotCache::default(),
            later: None,
            idle: Box::pin(tokio::time::sleep(idle_timeout)),
            waiting: false,
            wait: limits.first,
            idle_timeout,
            shutting_down: Box::pin(shutdown.clone().cancelled_owned()),
            shutdown,
            polls: 0,
            watched,
            ended: false,
            _done: done.drop_guard(),
        }
    }
}

impl Stream for FkReplies {
    type Item = Result<pb::StreamForwardKinematicsResponse, Status>;

    fn poll_next(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        let this = self.get_mut();
        if this.ended {
            return Poll::Ready(None);
        }
        let next = this.next_reply(cx);
        // One plain store per poll: the watchdog only reads it.
        this.polls += 2;
        // Owed a poll unless the compute pool is to wake the call: a call
        // waiting for a message is woken by it or by its own deadline.
        let owed = !(next.is_pending() && this.later.is_some());
        this.watched
            .polls
            .store(this.polls | u64::from(owed), Ordering::Relaxed);
        this.ended = matches!(next, Poll::Ready(None | Some(Err(_))));
        next
    }
}

impl FkReplies {
    fn next_reply(
        &mut self,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<pb::StreamForwardKinematicsResponse, Status>>> {
        if self.shutdown.is_cancelled() {
            return Poll::Ready(Some(Err(closing())));
        }
        if self.watched.closed.load(Ordering::Relaxed) {
            return Poll::Ready(Some(Err(self.idle_status())));
        }
        if let Some(later) = self.later.as_mut() {
            let reply = ready!(later.as_mut().poll(cx));
            self.later = None;
            return Poll::Ready(Some(reply.map_err(Status::from)));
        }
        let msg = match Pin::new(&mut self.inbound).poll_next(cx) {
            Poll::Ready(Some(Ok(msg))) => msg,
            // Undecodable or oversized message (or the buffered bytes
            // budget spent): report it and end (the transport state is unknown).
            Poll::Ready(Some(Err(status))) => {
                return Poll::Ready(Some(Err(oversize::remap_status(status))));
            }
            Poll::Ready(None) => return Poll::Ready(None),
            Poll::Pending => return self.wait_for_message(cx),
        };
        self.waiting = false;
        self.wait = self.idle_timeout;
        // A bug (panic) while answering ends the stream with INTERNAL, not
        // with a clean end of stream the client would take for success.
        match self.grpc.stream_answer(msg, self.client, &mut self.robots) {
            Ok(Answer::Now(reply)) => Poll::Ready(Some(Ok(reply))),
            Ok(Answer::Later(mut later)) => match later.as_mut().poll(cx) {
                Poll::Ready(reply) => Poll::Ready(Some(reply.map_err(Status::from))),
                Poll::Pending => {
                    self.later = Some(later);
                    Poll::Pending
                }
            },
            Err(e) => Poll::Ready(Some(Err(Status::from(e)))),
        }
    }

    /// No message yet: the idle deadline (armed once per wait, not per
    /// poll) and the server's shutdown wake the call, as the message does.
    fn wait_for_message(
        &mut self,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<pb::StreamForwardKinematicsResponse, Status>>> {
        if !self.waiting {
            self.waiting = true;
            self.idle.as_mut().reset(Instant::now() + self.wait);
        }
        if self.idle.as_mut().poll(cx).is_ready() {
            return Poll::Ready(Some(Err(self.idle_status())));
        }
        if self.shutting_down.as_mut().poll(cx).is_ready() {
            return Poll::Ready(Some(Err(closing())));
        }
        Poll::Pending
    }

    fn idle_status(&self) -> Status {
        Status::from(Error::RequestTimeout {
            detail: format!(
                "stream idle timeout: no message from the client and no reply taken for {:?}",
                self.idle_timeout
            ),
        })
    }
}

fn closing() -> Status {
    Status::from(Error::Unavailable {
        detail: "server shutting down".into(),
    })
}

/// Checks per timeout the watchdog makes.
const CHECKS_PER_TIMEOUT: u32 = 4;

/// How long the watchdog lets a call be owed a poll: `first` until the
/// call has been polled once (the first-message timeout: a client whose
/// window is closed from the start is not polled at all), then `idle`.
#[derive(Clone, Copy)]
struct Limits {
    first: Duration,
    idle: Duration,
}

/// The watchdog of one call: holds `held` until the call is done (`done`
/// cancelled when the HTTP layer drops it), the server shuts down, or the
/// call has been owed a poll for its limit (checked [`CHECKS_PER_TIMEOUT`]
/// times per limit, so it acts within 1¼ × the limit). After the last two it
/// gives `held` back and closes the connection if the call is still not done
/// after [`streams::STUCK_GRACE`]; after idleness a later poll of the call
/// answers `DEADLINE_EXCEEDED` (after a shutdown, the call reports that).
async fn watch(
    watched: Arc<Watched>,
    done: CancellationToken,
    shutdown: CancellationToken,
    limits: Limits,
    held: (StreamPermit, StreamGuard),
    connection: Option<streams::GrpcConnInfo>,
) {
    let mut last = u64::MAX;
    let mut owed_for = Duration::ZERO;
    loop {
        // Until the call's first poll (`last` is 1 or not read yet), the
        // first-message limit; then the idle timeout, so a long-lived
        // stream's watchdog wakes four times per idle timeout.
        let limit = if last <= 1 || last == u64::MAX {
            limits.first
        } else {
            limits.idle
        };
        let tick = limit / CHECKS_PER_TIMEOUT;
        tokio::select! {
            _ = done.cancelled() => return,
            _ = shutdown.cancelled() => break,
            _ = tokio::time::sleep(tick) => {}
        }
        let polls = watched.polls.load(Ordering::Relaxed);
        if polls != last || polls & 1 == 0 {
            (last, owed_for) = (polls, Duration::ZERO);
            continue;
        }
        owed_for += tick;
        if owed_for >= limit {
            watched.closed.store(true, Ordering::Relaxed);
            break;
        }
    }
    drop(held);
    close_if_stuck(done, connection).await;
}

/// After the server gave a call up (idle timeout, shutdown): if it is not
/// done within [`streams::STUCK_GRACE`] (the HTTP/2 layer still waits for
/// the client's window to send a reply or the final status), closes its
/// connection, the only way to end that stream (see `streams`). A client
/// that reads gets the final status at once and keeps its connection.
async fn close_if_stuck(done: CancellationToken, connection: Option<streams::GrpcConnInfo>) {
    let finished = tokio::time::timeout(streams::STUCK_GRACE, done.cancelled()).await;
    if finished.is_err()
        && let Some(c) = connection
    {
        tracing::info!(
            "closing a gRPC connection: a closed stream on it stays blocked on the client's receive window"
        );
        c.close.cancel();
    }
}
