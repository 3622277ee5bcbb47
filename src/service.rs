//! The protocol-neutral service: what REST and gRPC both call. Adapters
//! validate and convert their wire types, call one method here, and convert back.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use subtle::ConstantTimeEq;

use crate::compute::{ClientId, ComputePool, cancelled, share_of, stopped};
use crate::error::{Error, Result};
use crate::kinematics::Transform;
use crate::model::operations::{ConfigAnswers, ConfigOp, ConfigOps, ConfigSpec};
use crate::model::{
    BatchPoses, FkBatchSpec, FkSpec, IkAnswer, IkBatchSpec, IkPathAnswer, IkPathSpec, IkSpec,
    JacobianAnswer, JacobianBatchSpec, JacobianSpec, JointBatch, LengthUnit, ModelLimits,
    PoseFormat, ReferenceFrame, Robot, RobotSpec, StreamOp,
};
use crate::registry::{ClosedFormResult, Condition, Entry, Origin, PutMode, Registry};

/// Limits the service enforces on requests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServiceLimits {
    /// Model size limits.
    pub model: ModelLimits,
    /// Most configurations (or IK targets) in one batch request (default 10,000).
    pub max_batch: usize,
    /// Longest time one IK solve may take (default 50 ms); past it the best
    /// attempt so far is answered.
    pub ik_time_limit: Duration,
    /// Longest time one IK batch may take (default 15 s, half the default
    /// request timeout); targets left when it runs out are answered unsolved.
    pub ik_batch_time_limit: Duration,
    /// Computations (IK, batches, closed forms, URDF) at once on the compute
    /// pool (default: one per CPU but one, at least one).
    pub compute_permits: usize,
    /// Percent of every budget one client may hold (default 50; at least one unit).
    pub client_share_percent: u8,
}

impl ServiceLimits {
    /// Default of [`ServiceLimits::ik_time_limit`].
    pub const DEFAULT_IK_TIME_LIMIT: Duration = Duration::from_millis(50);
}

impl Default for ServiceLimits {
    fn default() -> Self {
        Self {
            model: ModelLimits::default(),
            max_batch: 10_000,
            ik_time_limit: Self::DEFAULT_IK_TIME_LIMIT,
            ik_batch_time_limit: Duration::from_secs(15),
            compute_permits: ComputePool::default_permits(),
            client_share_percent: 50,
        }
    }
}

/// A line of the robot list.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotSummary {
    /// Name.
    pub name: String,
    /// Number of movable joints.
    pub dof: usize,
    /// DH convention.
    pub convention: crate::model::ConventionSpec,
    /// Length unit of its positions.
    pub length_unit: LengthUnit,
    /// Built-in or registered.
    pub origin: Origin,
    /// Closed-form IK class, if any ([`crate::model::Robot::ik_class`]).
    pub ik_class: Option<&'static str>,
}

pub use crate::model::Configurations;

/// Who may register, replace and delete robots.
#[derive(Clone, PartialEq, Eq)]
pub enum WriteAccess {
    /// Holders of this bearer token (`--api-token`).
    Token(String),
    /// Anyone who can reach the server (`--allow-unauthenticated-writes`).
    Open,
    /// Nobody: no token is configured (the default), so the registry is
    /// read-only; writes are 403 / PERMISSION_DENIED saying how to allow them.
    Closed,
}

impl std::fmt::Debug for WriteAccess {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            WriteAccess::Token(_) => "Token(<redacted>)",
            WriteAccess::Open => "Open",
            WriteAccess::Closed => "Closed",
        })
    }
}

/// What a write to a registry without a token is told.
pub const WRITES_CLOSED: &str = "the registry is read-only: no API token is configured. \
Start the server with --api-token (KINSERVE_API_TOKEN) and send `Authorization: Bearer <token>`, \
or with --allow-unauthenticated-writes on a network you trust";

/// The service shared by every front door.
#[derive(Debug)]
pub struct Service {
    registry: Registry,
    limits: ServiceLimits,
    ready: AtomicBool,
    writes: WriteAccess,
    pool: ComputePool,
}

/// The robot a stream's last message named, with the registry generation
/// it was looked up in (see [`Service::robot_cached`]). One per stream.
#[derive(Debug, Default)]
pub struct RobotCache(Option<(u64, Arc<Entry>)>);

impl Service {
    /// A service over `registry`; `writes` says who may change it.
    pub fn new(registry: Registry, limits: ServiceLimits, writes: WriteAccess) -> Service {
        let permits = limits.compute_permits;
        Service {
            registry,
            limits,
            ready: AtomicBool::new(false),
            writes,
            pool: ComputePool::new(permits, share_of(permits, limits.client_share_percent)),
        }
    }

    /// The compute pool the expensive operations run on.
    pub fn pool(&self) -> &ComputePool {
        &self.pool
    }

    /// Whether the service takes traffic (robots loaded, not shutting down).
    pub fn is_ready(&self) -> bool {
        self.ready.load(Ordering::Acquire)
    }

    /// Flips readiness (true once robots are loaded, false on shutdown).
    pub fn set_ready(&self, ready: bool) {
        self.ready.store(ready, Ordering::Release);
    }

    /// The limits in force.
    pub fn limits(&self) -> &ServiceLimits {
        &self.limits
    }

    /// The registry.
    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Checks a presented bearer token in constant time. Passes anyone when
    /// writes are open; refuses everyone (403, [`WRITES_CLOSED`]) when no
    /// token is configured and writes are not opened.
    pub fn authorize(&self, presented: Option<&str>) -> Result<()> {
        let expected = match &self.writes {
            WriteAccess::Token(t) => t,
            WriteAccess::Open => return Ok(()),
            WriteAccess::Closed => {
                let cert = crate::tls::peer::current_subject();
                let client_cert = cert.as_deref();
                tracing::info!(target: "kinserve::audit", client_cert, result = "refused", "registry change refused: no API token configured (read-only registry)");
                return Err(Error::Forbidden {
                    detail: WRITES_CLOSED.into(),
                });
            }
        };
        match presented {
            Some(p) if bool::from(p.as_bytes().ct_eq(expected.as_bytes())) => Ok(()),
            _ => {
                let token = if presented.is_some() {
                    "wrong"
                } else {
                    "missing"
                };
                let cert = crate::tls::peer::current_subject();
                let client_cert = cert.as_deref();
                tracing::info!(target: "kinserve::audit", token, client_cert, result = "refused", "registry change refused: missing or invalid bearer token");
                Err(Error::Unauthenticated)
            }
        }
    }

    /// Checks an `Authorization` header (HTTP) or metadata value (gRPC) of the form
    /// `Bearer <token>` (scheme case-insensitive), as [`Service::authorize`].
    pub fn authorize_header(&self, authorization: Option<&str>) -> Result<()> {
        let token = authorization.and_then(|v| {
            let (scheme, token) = v.split_once(' ')?;
            scheme.eq_ignore_ascii_case("bearer").then(|| token.trim())
        });
        self.authorize(token)
    }

    /// Every robot, sorted by name.
    pub fn list(&self) -> Vec<RobotSummary> {
        self.registry
            .list()
            .iter()
            .map(|e| RobotSummary {
                name: e.robot.name().to_string(),
                dof: e.robot.dof(),
                convention: e.robot.spec().convention,
                length_unit: e.robot.length_unit(),
                origin: e.origin,
                ik_class: e.robot.ik_class(),
            })
            .collect()
    }

    /// One page of the robot list (AIP-158): at most `page_size` robots
    /// ([`DEFAULT_PAGE_SIZE`] when 0, [`MAX_PAGE_SIZE`] at most), sorted by name,
    /// starting after the robot that `page_token` (from the previous page's
    /// answer) names. The token of the next page is `None` on the last page.
    pub fn list_page(
        &self,
        page_size: u32,
        page_token: &str,
    ) -> Result<(Vec<RobotSummary>, Option<String>)> {
        let after = match page_token {
            "" => None,
            t => Some(decode_page_token(t).ok_or_else(|| {
                Error::malformed_field(
                    "page_token",
                    "not a page token this server issued: pass next_page_token from the previous page unchanged",
                )
            })?),
        };
        let size = match page_size {
            0 => DEFAULT_PAGE_SIZE,
            n => (n as usize).min(MAX_PAGE_SIZE),
        };
        let all = self.list();
        let start = after.map_or(0, |a| {
            all.partition_point(|r| r.name.as_str() <= a.as_str())
        });
        let page: Vec<RobotSummary> = all.into_iter().skip(start).take(size + 1).collect();
        let (page, next) = if page.len() > size {
            let mut page = page;
            page.truncate(size);
            let next = page.last().map(|r| encode_page_token(&r.name));
            (page, next)
        } else {
            (page, None)
        };
        Ok((page, next))
    }

    /// The robot called `name`. An empty name is malformed input; an unknown
    /// one is [`Error::NotFound`] with the nearest existing names.
    pub fn robot(&self, name: &str) -> Result<Arc<Entry>> {
        self.robot_at(name, "name")
    }

    /// [`Service::robot`] for a request whose robot name is in field `field`
    /// (`robot` in the gRPC FK messages), which an empty name is reported against.
    pub fn robot_at(&self, name: &str, field: &str) -> Result<Arc<Entry>> {
        if name.is_empty() {
            return Err(Error::malformed_field(
                field,
                "must not be empty: give a robot name (GET /v1/robots or ListRobots lists them)",
            ));
        }
        let entry = self.registry.get(name).ok_or_else(|| Error::NotFound {
            name: truncate_name(name),
            suggestions: self.nearest_names(name),
        })?;
        crate::telemetry::spans::record_robot(entry.robot.name());
        Ok(entry)
    }

    /// [`Service::robot_at`] for a stream's message: the entry `cache` holds
    /// when the message names the same robot and the registry has not
    /// changed since (no map lookup, no hashing of the name), else looked up
    /// and kept. A robot replaced or deleted mid-stream is seen by the next
    /// message, as with a lookup per message.
    pub fn robot_cached(
        &self,
        cache: &mut RobotCache,
        name: &str,
        field: &str,
    ) -> Result<Arc<Entry>> {
        let generation = self.registry.generation();
        if let Some((kept, entry)) = &cache.0
            && *kept == generation
            && entry.robot.name() == name
        {
            crate::telemetry::spans::record_robot(name);
            return Ok(Arc::clone(entry));
        }
        let entry = self.robot_at(name, field)?;
        cache.0 = Some((generation, Arc::clone(&entry)));
        Ok(entry)
    }

    /// Up to three existing names close to `name`: equal ignoring case,
    /// `-`, `_` and spaces, or within a small edit distance, best first. The
    /// registry bounds the work (see [`crate::registry::names`]).
    fn nearest_names(&self, name: &str) -> Vec<String> {
        self.registry.nearest_names(name)
    }

    /// The closed-form FK of robot `name`'s DH table (see [`ClosedForm`](crate::model::ClosedForm)),
    /// computed once per robot version on the compute pool (`client`'s
    /// share) and kept; too large to print is [`Error::TooLarge`] on `links`.
    pub async fn closed_form(&self, client: ClientId, name: &str) -> Result<Arc<ClosedFormResult>> {
        let entry = self.robot(name)?;
        if let Some(known) = entry.closed_form_if_known() {
            return Ok(known);
        }
        self.pool
            .run(client, move |_| Ok(entry.closed_form()))
            .await
    }

    /// Robot `name` as a URDF document (metres, radians), written on the compute pool.
    pub async fn urdf(&self, client: ClientId, name: &str) -> Result<String> {
        let entry = self.robot(name)?;
        self.pool
            .run(client, move |_| Ok(crate::model::to_urdf(&entry.robot)))
            .await
    }

    /// The robot model of a URDF import ([`crate::model::import_urdf_with`],
    /// under the model limits), converted and checked on the compute pool
    /// under one of `client`'s permits.
    pub async fn import_urdf(
        &self,
        client: ClientId,
        req: crate::model::UrdfImport,
    ) -> Result<RobotSpec> {
        let limits = self.limits.model;
        self.pool
            .run(client, move |_| {
                Ok(crate::model::import_urdf_with(&req, &limits)?)
            })
            .await
    }

    /// Validates and registers a model, durably, if `cond` holds (`If-Match`,
    /// `If-None-Match: *`, gRPC `etag`). Returns the new entry and whether it
    /// was created (else it replaced a registered robot). Writes one audit line.
    pub async fn register(
        self: &Arc<Self>,
        spec: RobotSpec,
        mode: PutMode,
        cond: Condition,
    ) -> Result<(Arc<Entry>, bool)> {
        let name = truncate_name(&spec.name);
        let result = self.register_inner(spec, mode, cond).await;
        let action = match (mode, &result) {
            (_, Ok((_, true))) | (PutMode::Create, _) => "register",
            (PutMode::Upsert, _) => "replace",
        };
        self.audit(action, &name, &result);
        result
    }

    async fn register_inner(
        self: &Arc<Self>,
        spec: RobotSpec,
        mode: PutMode,
        cond: Condition,
    ) -> Result<(Arc<Entry>, bool)> {
        let robot = crate::trace_span!("validate")
            .in_scope(|| Robot::from_spec(spec, &self.limits.model))?;
        crate::telemetry::spans::record_robot(robot.name());
        let this = Arc::clone(self);
        let write = crate::trace_span!("store write", operation = "put");
        let put = tokio::task::spawn_blocking(move || {
            write.in_scope(|| this.registry.put(robot, mode, cond))
        })
        .await
        .map_err(|e| Error::Internal {
            detail: e.to_string(),
        })??;
        self.record_robot_count();
        Ok(put)
    }

    /// Deletes a registered robot, durably, if `cond` holds. Writes one audit line.
    pub async fn delete(self: &Arc<Self>, name: &str, cond: Condition) -> Result<()> {
        let this = Arc::clone(self);
        let owned = name.to_string();
        let write = crate::trace_span!("store write", operation = "delete");
        let result = tokio::task::spawn_blocking(move || {
            write.in_scope(|| this.registry.delete(&owned, cond))
        })
        .await
        .map_err(|e| Error::Internal {
            detail: e.to_string(),
        })
        .and_then(|r| r);
        if result.is_ok() {
            self.record_robot_count();
        }
        self.audit("delete", &truncate_name(name), &result);
        result
    }

    /// One audit line per registry change (target `kinserve::audit`): what,
    /// which robot, the outcome, and who — whether a bearer token was
    /// required and so presented (the token itself is never logged), and
    /// the subject of the connection's TLS client certificate, if any.
    fn audit<T>(&self, action: &str, robot: &str, result: &Result<T>) {
        let who = match self.writes {
            WriteAccess::Token(_) => "bearer token",
            WriteAccess::Open => "anyone (--allow-unauthenticated-writes)",
            WriteAccess::Closed => "nobody (no API token configured)",
        };
        let cert = crate::tls::peer::current_subject();
        let client_cert = cert.as_deref();
        match result {
            Ok(_) => {
                tracing::info!(target: "kinserve::audit", action, robot, who, client_cert, result = "ok", "registry change")
            }
            Err(e) => {
                tracing::info!(target: "kinserve::audit", action, robot, who, client_cert, result = "refused", error = %e, "registry change refused")
            }
        }
    }

    /// Publishes the robot counts as gauges.
    pub fn record_robot_count(&self) {
        let (builtin, registered) = self.registry.counts();
        metrics::gauge!("kinserve_robots", "source" => "builtin").set(builtin as f64);
        metrics::gauge!("kinserve_robots", "source" => "registered").set(registered as f64);
    }

    /// Checked FK of one configuration: the tool pose, and every frame when
    /// the request asks for them (see [`crate::model::JointVector::fk_frames`]).
    pub fn fk(&self, robot: &Robot, spec: &FkSpec) -> Result<FkAnswer> {
        let q = crate::trace_span!("validate")
            .in_scope(|| robot.check_joints(&spec.joints, &spec.options))?;
        let (pose, frames) =
            crate::trace_span!("compute").in_scope(|| q.fk_with_frames(spec.frames));
        Ok(FkAnswer { pose, frames })
    }

    /// Checked answer of an operation on one configuration
    /// ([`crate::model::operations`]): validated once, computed on this task.
    pub fn config_op<Op: ConfigOp>(&self, robot: &Robot, spec: &ConfigSpec) -> Result<Op::Answer> {
        let q = crate::trace_span!("validate")
            .in_scope(|| robot.check_joints(&spec.joints, &spec.options))?;
        Ok(crate::trace_span!("compute").in_scope(|| Op::compute(&q)))
    }

    /// Checks a batch size against the limit before anything is decoded further.
    pub fn check_batch_size(&self, count: usize) -> Result<()> {
        crate::telemetry::spans::record_batch_size(count);
        if count > self.limits.max_batch {
            return Err(Error::TooLarge {
                detail: format!(
                    "a batch holds at most {} configurations, got {count}",
                    self.limits.max_batch
                ),
                field: Some("configurations".into()),
            });
        }
        Ok(())
    }

    /// Checked FK of many configurations, poses in request order. One bad
    /// configuration fails the whole batch, naming it (`configurations[17][2]`).
    pub fn fk_batch(&self, robot: &Robot, spec: &FkBatchSpec) -> Result<Vec<Transform>> {
        self.fk_batch_with(robot, spec, FkBatchCompute::TRANSFORMS)
    }

    /// [`Service::fk_batch`] with the poses in the spec's format, the
    /// compact ones written by the kernel straight into the answer's one
    /// vector ([`JointBatch::fk_as`]), for the binary and gRPC answers.
    pub fn fk_batch_as_format(&self, robot: &Robot, spec: &FkBatchSpec) -> Result<BatchPoses> {
        self.fk_batch_with(robot, spec, FkBatchCompute::IN_FORMAT)
    }

    /// Checks the batch, then `compute` on it.
    fn fk_batch_with<T>(
        &self,
        robot: &Robot,
        spec: &FkBatchSpec,
        compute: FkBatchCompute<T>,
    ) -> Result<T> {
        let c = &spec.configurations;
        self.check_batch_size(c.len())?;
        let batch = crate::trace_span!("validate")
            .in_scope(|| robot.check_batch(&c.values, &c.lens, &spec.options))?;
        Ok(
            crate::trace_span!("compute", kinserve.batch_size = c.len() as i64)
                .in_scope(|| (compute.0)(&batch, spec.pose_format)),
        )
    }
}

/// Velocity and inverse kinematics: the Jacobian (cheap, on the caller's
/// thread) and IK (up to [`ServiceLimits::ik_time_limit`] per target, so the
/// async front doors run it through [`Service::ik_on_pool`]).
impl Service {
    /// Checked Jacobian of one configuration in the request's frame, with its measures.
    pub fn jacobian(&self, robot: &Robot, spec: &JacobianSpec) -> Result<JacobianAnswer> {
        let q = crate::trace_span!("validate")
            .in_scope(|| robot.check_joints(&spec.joints, &spec.options))?;
        Ok(crate::trace_span!("compute").in_scope(|| q.jacobian(spec.frame)))
    }

    /// Checked Jacobians of many configurations, in request order; one bad
    /// configuration fails the batch, naming it (`configurations[17][2]`).
    /// Each configuration is validated once.
    pub fn jacobian_batch(
        &self,
        robot: &Robot,
        spec: &JacobianBatchSpec,
    ) -> Result<Vec<JacobianAnswer>> {
        self.jacobian_batch_cancellable(robot, spec, &AtomicBool::new(false))
    }

    /// [`Service::jacobian_batch`] that stops (checked every [`CANCEL_CHUNK`]
    /// configurations) once `cancel` is set.
    fn jacobian_batch_cancellable(
        &self,
        robot: &Robot,
        spec: &JacobianBatchSpec,
        cancel: &AtomicBool,
    ) -> Result<Vec<JacobianAnswer>> {
        let c = &spec.configurations;
        self.check_batch_size(c.len())?;
        let batch = crate::trace_span!("validate")
            .in_scope(|| robot.check_batch(&c.values, &c.lens, &spec.options))?;
        let _compute =
            crate::trace_span!("compute", kinserve.batch_size = c.len() as i64).entered();
        let mut out = Vec::with_capacity(batch.len());
        for (i, q) in batch.vectors().enumerate() {
            if i.is_multiple_of(CANCEL_CHUNK) && cancelled(cancel) {
                return Err(stopped());
            }
            out.push(q.jacobian(spec.frame));
        }
        Ok(out)
    }

    /// Validates and solves one IK request on this thread (up to
    /// [`ServiceLimits::ik_time_limit`]). Not converged is
    /// [`Error::IkNotConverged`] carrying the best attempt.
    pub fn ik(&self, robot: &Robot, spec: &IkSpec) -> Result<IkAnswer> {
        self.ik_cancellable(robot, spec, &AtomicBool::new(false))
    }

    /// [`Service::ik`] that gives up within one iteration once `cancel` is
    /// set ([`crate::compute::stopped`]).
    fn ik_cancellable(
        &self,
        robot: &Robot,
        spec: &IkSpec,
        cancel: &AtomicBool,
    ) -> Result<IkAnswer> {
        let request = crate::trace_span!("validate").in_scope(|| robot.check_ik(spec))?;
        let _compute = crate::trace_span!("compute").entered();
        // A limit too long to represent (set in code; the command line caps it) is no limit.
        let deadline = Instant::now().checked_add(self.limits.ik_time_limit);
        let answer = request.solve_cancellable(deadline, cancel);
        if cancelled(cancel) {
            return Err(stopped());
        }
        metrics::counter!("kinserve_ik_solves_total", "converged" => if answer.converged { "true" } else { "false" }).increment(1);
        if answer.converged {
            Ok(answer)
        } else {
            Err(Error::ik_not_converged(
                answer,
                robot.length_unit().as_str(),
            ))
        }
    }

    /// Validates and solves an IK batch on this thread: every target
    /// answered in order, converged or not (see [`IkBatch::solve`](crate::model::IkBatch::solve)).
    pub fn ik_batch(&self, robot: &Robot, spec: &IkBatchSpec) -> Result<Vec<IkAnswer>> {
        self.ik_batch_cancellable(robot, spec, &AtomicBool::new(false))
    }

    fn ik_batch_cancellable(
        &self,
        robot: &Robot,
        spec: &IkBatchSpec,
        cancel: &AtomicBool,
    ) -> Result<Vec<IkAnswer>> {
        self.check_batch_size(spec.targets.len())
            .map_err(|_| self.targets_too_large(spec.targets.len()))?;
        let batch = crate::trace_span!("validate").in_scope(|| robot.check_ik_batch(spec))?;
        let _compute =
            crate::trace_span!("compute", kinserve.batch_size = spec.targets.len() as i64)
                .entered();
        let now = Instant::now();
        let deadline = deadline_after(now, self.limits.ik_batch_time_limit);
        // No target gets more than the whole batch has (so no sum overflows either).
        let per_target = self
            .limits
            .ik_time_limit
            .min(deadline.saturating_duration_since(now));
        let answers = batch.solve_cancellable(per_target, deadline, cancel);
        if cancelled(cancel) {
            return Err(stopped());
        }
        let converged = answers.iter().filter(|a| a.converged).count() as u64;
        metrics::counter!("kinserve_ik_solves_total", "converged" => "true").increment(converged);
        metrics::counter!("kinserve_ik_solves_total", "converged" => "false")
            .increment(answers.len() as u64 - converged);
        Ok(answers)
    }

    /// Validates and solves a Cartesian path on this thread: each step under
    /// [`ServiceLimits::ik_time_limit`], the whole path under
    /// [`ServiceLimits::ik_batch_time_limit`] (then it stops with
    /// `time_limit`), at most [`ServiceLimits::max_batch`] steps.
    pub fn ik_path(&self, robot: &Robot, spec: &IkPathSpec) -> Result<IkPathAnswer> {
        self.ik_path_cancellable(robot, spec, &AtomicBool::new(false))
    }

    fn ik_path_cancellable(
        &self,
        robot: &Robot,
        spec: &IkPathSpec,
        cancel: &AtomicBool,
    ) -> Result<IkPathAnswer> {
        if spec.waypoints.len() > self.limits.max_batch {
            return Err(Error::TooLarge {
                detail: format!(
                    "a path holds at most {} waypoints, got {}",
                    self.limits.max_batch,
                    spec.waypoints.len()
                ),
                field: Some("waypoints".into()),
            });
        }
        let path = robot.check_ik_path(spec, self.limits.max_batch)?;
        let now = Instant::now();
        let deadline = deadline_after(now, self.limits.ik_batch_time_limit);
        let answer = path.solve_cancellable(self.limits.ik_time_limit, Some(deadline), cancel);
        if cancelled(cancel) {
            return Err(stopped());
        }
        let outcome = answer
            .stop
            .as_ref()
            .map_or("complete", |s| s.reason.as_str());
        metrics::counter!("kinserve_ik_paths_total", "outcome" => outcome).increment(1);
        Ok(answer)
    }

    /// [`Service::ik_path`] on the compute pool; stops when the caller does.
    pub async fn ik_path_on_pool(
        self: &Arc<Self>,
        client: ClientId,
        robot: Arc<Entry>,
        spec: IkPathSpec,
    ) -> Result<IkPathAnswer> {
        let this = Arc::clone(self);
        self.pool
            .run(client, move |cancel| {
                this.ik_path_cancellable(&robot.robot, &spec, cancel)
            })
            .await
    }

    fn targets_too_large(&self, count: usize) -> Error {
        Error::TooLarge {
            detail: format!(
                "a batch holds at most {} targets, got {count}",
                self.limits.max_batch
            ),
            field: Some("targets".into()),
        }
    }

    /// [`Service::ik`] on the compute pool under one of `client`'s permits
    /// (refused at once when none is free); stops when the caller does.
    pub async fn ik_on_pool(
        self: &Arc<Self>,
        client: ClientId,
        robot: Arc<Entry>,
        spec: IkSpec,
    ) -> Result<IkAnswer> {
        let this = Arc::clone(self);
        self.pool
            .run(client, move |cancel| {
                this.ik_cancellable(&robot.robot, &spec, cancel)
            })
            .await
    }

    /// [`Service::ik_batch`] on the compute pool; stops when the caller does.
    pub async fn ik_batch_on_pool(
        self: &Arc<Self>,
        client: ClientId,
        robot: Arc<Entry>,
        spec: IkBatchSpec,
    ) -> Result<Vec<IkAnswer>> {
        let this = Arc::clone(self);
        self.pool
            .run(client, move |cancel| {
                this.ik_batch_cancellable(&robot.robot, &spec, cancel)
            })
            .await
    }

    /// [`Service::fk_batch`] on the compute pool, under one of `client`'s
    /// permits; a batch of at most [`FK_BATCH_INLINE`] configurations on the
    /// caller's thread instead, as a single FK is.
    /// `compute` says what the poses are computed into
    /// ([`FkBatchCompute::TRANSFORMS`] for JSON answers,
    /// [`FkBatchCompute::IN_FORMAT`] for binary and gRPC ones).
    pub async fn fk_batch_on_pool<T: Send + 'static>(
        self: &Arc<Self>,
        client: ClientId,
        robot: Arc<Entry>,
        spec: FkBatchSpec,
        compute: FkBatchCompute<T>,
    ) -> Result<(T, FkBatchSpec)> {
        if spec.configurations.len() <= FK_BATCH_INLINE {
            let poses = self.fk_batch_with(&robot.robot, &spec, compute)?;
            return Ok((poses, spec));
        }
        self.check_batch_size(spec.configurations.len())?;
        let this = Arc::clone(self);
        self.pool
            .run(client, move |_| {
                // One kernel pass: 10,000 poses take well under a millisecond.
                let poses = this.fk_batch_with(&robot.robot, &spec, compute)?;
                Ok((poses, spec))
            })
            .await
    }

    /// [`Service::jacobian_batch`] on the compute pool; stops (checked every
    /// [`CANCEL_CHUNK`] configurations) when the caller does.
    pub async fn jacobian_batch_on_pool(
        self: &Arc<Self>,
        client: ClientId,
        robot: Arc<Entry>,
        spec: JacobianBatchSpec,
    ) -> Result<Vec<JacobianAnswer>> {
        // Refused before a permit is taken; checked again inside (cheap).
        self.check_batch_size(spec.configurations.len())?;
        let this = Arc::clone(self);
        self.pool
            .run(client, move |cancel| {
                this.jacobian_batch_cancellable(&robot.robot, &spec, cancel)
            })
            .await
    }
}

/// Configurations computed between two looks at the cancel flag (a few
/// hundred microseconds of Jacobians).
pub const CANCEL_CHUNK: usize = 64;

/// FK batches (REST and gRPC batches, stream messages of many
/// configurations) of at most this many configurations are computed on the
/// caller's thread, not on the compute pool: checking and computing 256
/// poses takes a few microseconds (about 15–30 ns a pose in release), less
/// than handing the work to a pool thread and back, which made a stream
/// message of 4 configurations slower than 4 messages of one. Larger
/// batches take a pool permit and the client's share as before.
pub const FK_BATCH_INLINE: usize = 256;

/// The answer to one FK request: the tool pose, and every frame when asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct FkAnswer {
    /// Tool pose `^world T_tool`.
    pub pose: Transform,
    /// `^world T_i` for `i = 0..=rows`, when asked for.
    pub frames: Option<Vec<Transform>>,
}

/// The answer to one stream message ([`Service::stream_step`]).
#[derive(Clone, Debug, PartialEq)]
pub enum StreamAnswer {
    /// FK: the tool pose (the Jacobian's when it was asked for; the same pose),
    /// frames, the Jacobian and the operations on one configuration as asked for.
    Fk {
        /// Tool pose and frames.
        fk: FkAnswer,
        /// How the message asked for its poses.
        pose_format: PoseFormat,
        /// The Jacobian, when asked for.
        jacobian: Option<JacobianAnswer>,
        /// The operations on one configuration, those asked for.
        ops: ConfigAnswers,
    },
    /// IK: the answer (converged; not converged is an error).
    Ik(IkAnswer),
    /// A Cartesian path (stopped early is an answer, with its stop).
    IkPath(IkPathAnswer),
    /// FK of many configurations: the poses in request order, as the FK
    /// batch answers them.
    FkBatch {
        /// One tool pose per configuration.
        poses: Vec<Transform>,
        /// How the message asked for its poses.
        pose_format: PoseFormat,
    },
}

/// What an FK batch's poses are computed into, from the checked batch and
/// the spec's pose format: a plain function, so it crosses to the compute
/// pool without capturing anything.
pub struct FkBatchCompute<T>(fn(&JointBatch<'_>, PoseFormat) -> T);

impl<T> Clone for FkBatchCompute<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for FkBatchCompute<T> {}

impl FkBatchCompute<Vec<Transform>> {
    /// Transforms, whatever the format (the JSON answers are written from them).
    pub const TRANSFORMS: Self = FkBatchCompute(|batch, _| batch.fk());
}

impl FkBatchCompute<BatchPoses> {
    /// The poses in the spec's format ([`JointBatch::fk_as`]).
    pub const IN_FORMAT: Self = FkBatchCompute(|batch, format| batch.fk_as(format));
}

/// One stream message, the same for the WebSocket and the gRPC stream.
impl Service {
    /// Answers one stream message for `entry`: FK (with the Jacobian and the
    /// operations on one configuration when asked for, validated once) on
    /// this task; IK, paths and FK of many configurations on the compute pool
    /// under one of `client`'s permits (refused at once when none is free,
    /// as the unary batch is). Counts the poses under `protocol`.
    pub async fn stream_step(
        self: &Arc<Self>,
        entry: Arc<Entry>,
        op: StreamOp,
        protocol: crate::telemetry::Protocol,
        client: ClientId,
    ) -> Result<StreamAnswer> {
        // The compute-pool futures are boxed: unboxed, every FK message's
        // future would be as large as the largest of them and be copied
        // around per message (a fifth of the stream's server time).
        match op {
            StreamOp::Ik(spec) => Ok(StreamAnswer::Ik(
                Box::pin(self.ik_on_pool(client, entry, *spec)).await?,
            )),
            StreamOp::IkPath(spec) => Ok(StreamAnswer::IkPath(
                Box::pin(self.ik_path_on_pool(client, entry, *spec)).await?,
            )),
            StreamOp::FkBatch(spec) => {
                let (poses, spec) = Box::pin(self.fk_batch_on_pool(
                    client,
                    entry.clone(),
                    spec,
                    FkBatchCompute::TRANSFORMS,
                ))
                .await?;
                entry.count_poses(protocol, poses.len() as u64);
                Ok(StreamAnswer::FkBatch {
                    poses,
                    pose_format: spec.pose_format,
                })
            }
            StreamOp::Fk { fk, jacobian, ops } => {
                Self::stream_fk(&entry, &fk, jacobian, ops, protocol)
            }
        }
    }

    /// The FK step of [`Service::stream_step`] (one configuration, with the
    /// Jacobian and the operations on it when asked for): computed at once,
    /// so a stream may answer its FK messages without a future.
    pub fn stream_fk(
        entry: &Entry,
        fk: &FkSpec,
        jacobian: Option<ReferenceFrame>,
        ops: ConfigOps,
        protocol: crate::telemetry::Protocol,
    ) -> Result<StreamAnswer> {
        let q = entry.robot.check_joints(&fk.joints, &fk.options)?;
        let (pose, frames) = q.fk_with_frames(fk.frames);
        let jacobian = jacobian.map(|frame| q.jacobian(frame));
        // With the Jacobian, the pose is the Jacobian's (as `…/jacobian` answers it).
        let pose = jacobian.as_ref().map_or(pose, |j| j.pose);
        let ops = ops.compute(&q);
        entry.count_poses(protocol, 1);
        Ok(StreamAnswer::Fk {
            fk: FkAnswer { pose, frames },
            pose_format: fk.pose_format,
            jacobian,
            ops,
        })
    }
}

/// Robots in a list page when the client does not say (AIP-158 `page_size` 0).
pub const DEFAULT_PAGE_SIZE: usize = 100;
/// Most robots in one list page; larger `page_size` values are lowered to it.
pub const MAX_PAGE_SIZE: usize = 1000;

/// A page token: `n.` and the hex of the last name of the previous page
/// (opaque to clients; only this server's tokens decode).
fn encode_page_token(last: &str) -> String {
    let hex: String = last.bytes().map(|b| format!("{b:02x}")).collect();
    format!("n.{hex}")
}

fn decode_page_token(token: &str) -> Option<String> {
    let hex = token.strip_prefix("n.")?;
    if hex.len() % 2 != 0 || hex.len() > 256 {
        return None;
    }
    let bytes: Option<Vec<u8>> = (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(hex.get(i..i + 2)?, 16).ok())
        .collect();
    String::from_utf8(bytes?).ok()
}

/// Robot names echoed in errors are cut to 64 characters (a 10 KB name is not echoed back).
fn truncate_name(name: &str) -> String {
    let mut s: String = name.chars().take(64).collect();
    if s.len() < name.len() {
        s.push('…');
    }
    s
}

/// `now + limit`; a limit too long to represent (only possible when set in
/// code: the command line caps durations at a day) counts as a day.
fn deadline_after(now: Instant, limit: Duration) -> Instant {
    now.checked_add(limit)
        .or_else(|| now.checked_add(Duration::from_secs(24 * 60 * 60)))
        .unwrap_or(now)
}
