//! The protocol-neutral service: what REST and gRPC both call. Adapters
//! validate and convert their wire types, call one method here, and convert back.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use subtle::ConstantTimeEq;

use crate::error::{Error, Result};
use crate::kinematics::Transform;
use crate::model::{
    FkOptions, IkAnswer, IkBatchSpec, IkSpec, JacobianAnswer, LengthUnit, ModelLimits,
    ReferenceFrame, Robot, RobotSpec,
};
use crate::registry::{Entry, Origin, PutMode, Registry};

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
}

/// Many joint configurations stored back to back: `values` holds them all and
/// `lens[i]` is the length of configuration `i` (one allocation per request,
/// none per configuration).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Configurations {
    /// All values, configuration after configuration.
    pub values: Vec<f64>,
    /// Length of each configuration.
    pub lens: Vec<u32>,
}

impl Configurations {
    /// Number of configurations.
    pub fn len(&self) -> usize {
        self.lens.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.lens.is_empty()
    }

    /// Appends one configuration.
    pub fn push(&mut self, q: &[f64]) {
        self.values.extend_from_slice(q);
        self.lens.push(q.len() as u32);
    }
}

/// The service shared by every front door.
#[derive(Debug)]
pub struct Service {
    registry: Registry,
    limits: ServiceLimits,
    ready: AtomicBool,
    token: Option<String>,
    /// Handle of `kinserve_poses_computed_total`, resolved on first use (after the recorder is installed).
    poses: OnceLock<metrics::Counter>,
}

impl Service {
    /// A service over `registry`; `token`, if set, guards every mutation.
    pub fn new(registry: Registry, limits: ServiceLimits, token: Option<String>) -> Service {
        Service {
            registry,
            limits,
            ready: AtomicBool::new(false),
            token: token.filter(|t| !t.is_empty()),
            poses: OnceLock::new(),
        }
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

    /// Whether mutations need a token.
    pub fn auth_required(&self) -> bool {
        self.token.is_some()
    }

    /// Checks a presented bearer token in constant time. Passes when no token is configured.
    pub fn authorize(&self, presented: Option<&str>) -> Result<()> {
        let Some(expected) = &self.token else {
            return Ok(());
        };
        match presented {
            Some(p) if bool::from(p.as_bytes().ct_eq(expected.as_bytes())) => Ok(()),
            _ => Err(Error::Unauthenticated),
        }
    }

    /// Checks an `Authorization` header (HTTP) or metadata value (gRPC) of the form
    /// `Bearer <token>` (scheme case-insensitive). Passes when no token is configured.
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
            })
            .collect()
    }

    /// The robot called `name`.
    pub fn robot(&self, name: &str) -> Result<Arc<Entry>> {
        self.registry.get(name).ok_or_else(|| Error::NotFound {
            name: truncate_name(name),
        })
    }

    /// Validates and registers a model, durably. `Ok(true)` if created,
    /// `Ok(false)` if it replaced a registered robot.
    pub async fn register(self: &Arc<Self>, spec: RobotSpec, mode: PutMode) -> Result<bool> {
        let robot = Robot::from_spec(spec, &self.limits.model)?;
        let this = Arc::clone(self);
        let created = tokio::task::spawn_blocking(move || this.registry.put(robot, mode))
            .await
            .map_err(|e| Error::Internal {
                detail: e.to_string(),
            })??;
        self.record_robot_count();
        Ok(created)
    }

    /// Deletes a registered robot, durably.
    pub async fn delete(self: &Arc<Self>, name: &str) -> Result<()> {
        let this = Arc::clone(self);
        let name = name.to_string();
        tokio::task::spawn_blocking(move || this.registry.delete(&name))
            .await
            .map_err(|e| Error::Internal {
                detail: e.to_string(),
            })??;
        self.record_robot_count();
        Ok(())
    }

    fn poses_counter(&self) -> &metrics::Counter {
        self.poses
            .get_or_init(|| metrics::counter!("kinserve_poses_computed_total"))
    }

    /// Publishes the robot counts as gauges.
    pub fn record_robot_count(&self) {
        let (builtin, registered) = self.registry.counts();
        metrics::gauge!("kinserve_robots", "source" => "builtin").set(builtin as f64);
        metrics::gauge!("kinserve_robots", "source" => "registered").set(registered as f64);
    }

    /// Checked FK of one configuration: the tool pose.
    pub fn fk(&self, robot: &Robot, q: &[f64], opts: &FkOptions) -> Result<Transform> {
        let t = robot.check_joints(q, opts)?.fk();
        self.poses_counter().increment(1);
        Ok(t)
    }

    /// Checked FK of one configuration with every frame (see [`crate::model::JointVector::fk_frames`]).
    pub fn fk_frames(
        &self,
        robot: &Robot,
        q: &[f64],
        opts: &FkOptions,
    ) -> Result<(Transform, Vec<Transform>)> {
        let r = robot.check_joints(q, opts)?.fk_frames();
        self.poses_counter().increment(1);
        Ok(r)
    }

    /// Checked FK of one configuration: the tool pose, and every frame when
    /// `frames` is set — the one entry point the front doors call for single FK.
    pub fn fk_with_frames(
        &self,
        robot: &Robot,
        q: &[f64],
        opts: &FkOptions,
        frames: bool,
    ) -> Result<(Transform, Option<Vec<Transform>>)> {
        let r = robot.check_joints(q, opts)?.fk_with_frames(frames);
        self.poses_counter().increment(1);
        Ok(r)
    }

    /// Checks a batch size against the limit before anything is decoded further.
    pub fn check_batch_size(&self, count: usize) -> Result<()> {
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
    pub fn fk_batch(
        &self,
        robot: &Robot,
        configs: &Configurations,
        opts: &FkOptions,
    ) -> Result<Vec<Transform>> {
        self.check_batch_size(configs.len())?;
        let out = robot
            .check_batch(&configs.values, &configs.lens, opts)?
            .fk();
        self.poses_counter().increment(out.len() as u64);
        Ok(out)
    }
}

/// Velocity and inverse kinematics: the Jacobian (cheap, on the caller's
/// thread) and IK (up to [`ServiceLimits::ik_time_limit`] per target, so the
/// async front doors run it through [`Service::ik_blocking`]).
impl Service {
    /// Checked Jacobian of one configuration in `frame`, with its measures.
    pub fn jacobian(
        &self,
        robot: &Robot,
        q: &[f64],
        opts: &FkOptions,
        frame: ReferenceFrame,
    ) -> Result<JacobianAnswer> {
        let a = robot.check_joints(q, opts)?.jacobian(frame);
        self.poses_counter().increment(1);
        Ok(a)
    }

    /// Checked Jacobians of many configurations, in request order; one bad
    /// configuration fails the batch, naming it (`configurations[17][2]`).
    pub fn jacobian_batch(
        &self,
        robot: &Robot,
        configs: &Configurations,
        opts: &FkOptions,
        frame: ReferenceFrame,
    ) -> Result<Vec<JacobianAnswer>> {
        self.check_batch_size(configs.len())?;
        robot.check_batch(&configs.values, &configs.lens, opts)?;
        let mut out = Vec::with_capacity(configs.len());
        let mut offset = 0;
        for &len in &configs.lens {
            let q = configs
                .values
                .get(offset..offset + len as usize)
                .unwrap_or(&[]);
            out.push(robot.check_joints(q, opts)?.jacobian(frame));
            offset += len as usize;
        }
        self.poses_counter().increment(out.len() as u64);
        Ok(out)
    }

    /// Validates and solves one IK request on this thread (up to
    /// [`ServiceLimits::ik_time_limit`]). Not converged is
    /// [`Error::IkNotConverged`] carrying the best attempt.
    pub fn ik(&self, robot: &Robot, spec: &IkSpec) -> Result<IkAnswer> {
        let request = robot.check_ik(spec)?;
        let answer = request.solve(Some(Instant::now() + self.limits.ik_time_limit));
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
        self.check_batch_size(spec.targets.len())
            .map_err(|_| self.targets_too_large(spec.targets.len()))?;
        let batch = robot.check_ik_batch(spec)?;
        let deadline = Instant::now() + self.limits.ik_batch_time_limit;
        let answers = batch.solve(self.limits.ik_time_limit, deadline);
        let converged = answers.iter().filter(|a| a.converged).count() as u64;
        metrics::counter!("kinserve_ik_solves_total", "converged" => "true").increment(converged);
        metrics::counter!("kinserve_ik_solves_total", "converged" => "false")
            .increment(answers.len() as u64 - converged);
        Ok(answers)
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

    /// [`Service::ik`] on the blocking pool, so a long solve does not hold
    /// up the async front doors.
    pub async fn ik_blocking(
        self: &Arc<Self>,
        robot: Arc<Entry>,
        spec: IkSpec,
    ) -> Result<IkAnswer> {
        let this = Arc::clone(self);
        tokio::task::spawn_blocking(move || this.ik(&robot.robot, &spec))
            .await
            .map_err(|e| Error::Internal {
                detail: e.to_string(),
            })?
    }

    /// [`Service::ik_batch`] on the blocking pool.
    pub async fn ik_batch_blocking(
        self: &Arc<Self>,
        robot: Arc<Entry>,
        spec: IkBatchSpec,
    ) -> Result<Vec<IkAnswer>> {
        let this = Arc::clone(self);
        tokio::task::spawn_blocking(move || this.ik_batch(&robot.robot, &spec))
            .await
            .map_err(|e| Error::Internal {
                detail: e.to_string(),
            })?
    }
}

/// Robot names echoed in errors are cut to 64 characters (a 10 KB name is not echoed back).
fn truncate_name(name: &str) -> String {
    let mut s: String = name.chars().take(64).collect();
    if s.len() < name.len() {
        s.push('…');
    }
    s
}
