//! Validated joint vectors: [`Robot::check_joints`] and [`Robot::check_batch`]
//! (count, finiteness, magnitude and limits, each refusal under its field
//! path) and what they make, [`JointVector`] and [`JointBatch`]: the only
//! input a robot's FK accepts.
//!
//! Depends on [`crate::robot`] (the validated robot and its joints),
//! [`crate::pose_format`] (the formats a batch is answered in) and
//! [`crate::error`]; `robot.rs` must not depend on this module.

use kinserve_kinematics::{JointKind, PackedLayout, Transform};

use crate::error::{ModelError, Result};
use crate::pose_format::{BatchPoses, PoseFormat};
use crate::robot::{FkOptions, Joint, Robot, round6};
use crate::spec::AngleUnit;
use crate::{MAX_MAGNITUDE, MAX_REVOLUTE_RAD};

impl Robot {
    /// Checks a joint vector — count, finiteness, prismatic values within
    /// ±[`MAX_MAGNITUDE`] and (if asked) limits — and returns it as the
    /// validated [`JointVector`] that FK accepts. Field paths are `joints[i]`.
    ///
    /// ```
    /// use kinserve_model::{FkOptions, ModelLimits, Robot};
    ///
    /// let robot = Robot::from_json(br#"{"name": "slide-arm", "convention": "standard", "links": [
    ///     {"joint": "revolute", "a": 0.4, "alpha": 0, "d": 0, "theta": 0, "limits": [-1.5, 1.5]},
    ///     {"joint": "prismatic", "a": 0, "alpha": 0, "d": 0.1, "theta": 0, "limits": [0, 0.2]}
    /// ]}"#, &ModelLimits::default())?;
    /// let opts = FkOptions::default(); // rad, limits checked
    ///
    /// let q = robot.check_joints(&[0.5, 0.1], &opts)?;
    /// assert_eq!(q.values(), &[0.5, 0.1]);
    /// let [x, y, z] = q.fk().position(); // Rz(0.5)·Tx(0.4), then Tz(0.1 + 0.1)
    /// assert!((x - 0.4 * 0.5f64.cos()).abs() < 1e-12);
    /// assert!((y - 0.4 * 0.5f64.sin()).abs() < 1e-12 && (z - 0.2).abs() < 1e-12);
    ///
    /// // Wrong count, a non-finite value, a value beyond its limits:
    /// let field = |q: &[f64]| robot.check_joints(q, &opts).unwrap_err().violations()[0].field.clone();
    /// assert_eq!(field(&[0.5]), "joints");
    /// assert_eq!(field(&[0.5, f64::NAN]), "joints[1]");
    /// assert_eq!(field(&[2.0, 0.1]), "joints[0]");
    /// // ... which passes when limits are not checked.
    /// assert!(robot.check_joints(&[2.0, 0.1], &FkOptions::new(None, Some(false))).is_ok());
    /// # Ok::<(), kinserve_model::ModelError>(())
    /// ```
    pub fn check_joints<'a>(&'a self, q: &'a [f64], opts: &FkOptions) -> Result<JointVector<'a>> {
        self.check_joints_at(q, opts, || "joints".to_string())
    }

    /// Like [`Robot::check_joints`], with the vector's field path given lazily
    /// (e.g. `configurations[17]`, giving `configurations[17][2]`).
    pub fn check_joints_at<'a>(
        &'a self,
        q: &'a [f64],
        opts: &FkOptions,
        field: impl Fn() -> String,
    ) -> Result<JointVector<'a>> {
        if q.len() != self.dof() {
            return Err(ModelError::invalid_field(
                field(),
                format!(
                    "robot '{}' has {} movable joints, got {} values",
                    self.name(),
                    self.dof(),
                    q.len()
                ),
            ));
        }
        // The common case, every value good, in one pass of comparisons (see
        // `batch_within_bounds`: it accepts exactly what `check_value` does).
        let to_rad = opts.angle_unit.to_rad();
        let good = |(x, j): (&f64, &Joint)| {
            let [scale, lo, hi] = bounds(j, to_rad, opts.check_limits);
            let y = x * scale;
            (y >= lo) & (y <= hi)
        };
        if q.iter().zip(self.joints()).all(good) {
            return Ok(JointVector::new(self, q, to_rad));
        }
        for (i, (x, j)) in q.iter().zip(self.joints()).enumerate() {
            if let Some(mut message) = self.check_value(*x, j, opts) {
                if x.abs() > std::f64::consts::PI && self.looks_like_degrees(q, opts) {
                    message.push_str(
                        "; read as degrees every value is within the limits: send angle_unit \"deg\"",
                    );
                }
                return Err(ModelError::invalid_field(
                    format!("{}[{i}]", field()),
                    message,
                ));
            }
        }
        Ok(JointVector::new(self, q, opts.angle_unit.to_rad()))
    }

    /// Whether `q`, sent in rad, would keep every limit if its revolute values
    /// were degrees (the usual mistake: `[0, 90, -90]`). Asked only for an
    /// offending value beyond ±π, which is unlikely to be meant as radians.
    fn looks_like_degrees(&self, q: &[f64], opts: &FkOptions) -> bool {
        if opts.angle_unit != AngleUnit::Rad || !opts.check_limits {
            return false;
        }
        let deg = FkOptions {
            angle_unit: AngleUnit::Deg,
            check_limits: true,
        };
        q.iter()
            .zip(self.joints())
            .all(|(x, j)| self.check_value(*x, j, &deg).is_none())
    }

    /// What is wrong with value `x` of joint `j`, if anything.
    fn check_value(&self, x: f64, j: &Joint, opts: &FkOptions) -> Option<String> {
        if !x.is_finite() {
            return Some("must be a finite number".into());
        }
        if j.kind == JointKind::Prismatic && x.abs() > MAX_MAGNITUDE {
            let unit = self.length_unit().as_str();
            return Some(format!(
                "{x} {unit} is beyond ±{MAX_MAGNITUDE:e} {unit}, the largest prismatic joint value accepted"
            ));
        }
        let scale = opts.angle_unit.to_rad();
        if j.kind == JointKind::Revolute && (x * scale).abs() > MAX_REVOLUTE_RAD {
            let unit = opts.angle_unit.as_str();
            return Some(format!(
                "{x} {unit} is beyond ±{} {unit}, the largest revolute joint value accepted (±1e5 rad)",
                round6(MAX_REVOLUTE_RAD / scale)
            ));
        }
        let (lo, hi) = j.limits.filter(|_| opts.check_limits)?;
        let internal = if j.kind == JointKind::Revolute {
            x * scale
        } else {
            x
        };
        if internal >= lo && internal <= hi {
            return None;
        }
        Some(self.limits_message(x, lo, hi, j, opts.angle_unit))
    }

    /// "`x` unit is outside the limits [lo, hi] unit of joint 'name'", limits
    /// rounded to 6 significant digits in the request's unit, and in the
    /// model's own angle unit too when that differs.
    fn limits_message(&self, x: f64, lo: f64, hi: f64, j: &Joint, unit: AngleUnit) -> String {
        if j.kind != JointKind::Revolute {
            let u = self.length_unit().as_str();
            return format!(
                "{x} {u} is outside the limits [{}, {}] {u} of joint '{}'",
                round6(lo),
                round6(hi),
                j.name
            );
        }
        let k = 1.0 / unit.to_rad();
        let mut m = format!(
            "{x} {u} is outside the limits [{}, {}] {u} of joint '{}'",
            round6(lo * k),
            round6(hi * k),
            j.name,
            u = unit.as_str()
        );
        let model = self.spec().angle_unit;
        if model != unit {
            let km = 1.0 / model.to_rad();
            m.push_str(&format!(
                " ([{}, {}] {} in the model)",
                round6(lo * km),
                round6(hi * km),
                model.as_str()
            ));
        }
        m
    }

    /// Checks many configurations stored back to back (`lens[i]` values for
    /// configuration `i`); the first bad one fails the whole batch, naming it
    /// (`configurations[17][2]`).
    pub fn check_batch<'a>(
        &'a self,
        values: &'a [f64],
        lens: &[u32],
        opts: &FkOptions,
    ) -> Result<JointBatch<'a>> {
        let dof = self.dof();
        let whole = values.len() == dof * lens.len() && lens.iter().all(|&l| l as usize == dof);
        if whole && self.batch_within_bounds(values, opts) {
            return Ok(JointBatch::new(
                self,
                values,
                lens.len(),
                opts.angle_unit.to_rad(),
            ));
        }
        // Something is wrong: the per-value check finds it and says what.
        let mut offset = 0usize;
        for (i, &len) in lens.iter().enumerate() {
            let len = len as usize;
            let q = values.get(offset..offset + len).unwrap_or(&[]);
            self.check_joints_at(q, opts, || format!("configurations[{i}]"))?;
            offset += len;
        }
        Ok(JointBatch::new(
            self,
            &values[..offset.min(values.len())],
            lens.len(),
            opts.angle_unit.to_rad(),
        ))
    }

    /// Whether every value of `values` (configurations of `dof` values back
    /// to back) passes [`Robot::check_value`], in one branch-free pass: per
    /// joint the interval `x · scale` must lie in (scale 1 for a prismatic
    /// joint, the request's to-rad factor for a revolute one; the magnitude
    /// bound and, when checked, the limits). It accepts exactly what the
    /// per-value check accepts: the same products are compared with the same
    /// bounds, and NaN or ±∞ fall outside every finite interval.
    pub(crate) fn batch_within_bounds(&self, values: &[f64], opts: &FkOptions) -> bool {
        let dof = self.dof();
        if dof == 0 || !values.len().is_multiple_of(dof) {
            return values.is_empty();
        }
        let to_rad = opts.angle_unit.to_rad();
        let bounds: Vec<[f64; 3]> = self
            .joints()
            .iter()
            .map(|j| bounds(j, to_rad, opts.check_limits))
            .collect();
        // The bounds repeated for 8 configurations, as three flat rows: the
        // values then pass in runs of `8 × dof` against them, one flat loop
        // the compiler vectorises (per configuration it did not: `dof` is
        // not a vector width).
        let period = 8 * dof;
        let row =
            |k: usize| -> Vec<f64> { bounds.iter().cycle().take(period).map(|b| b[k]).collect() };
        let (scale, lo, hi) = (row(0), row(1), row(2));
        let within = |run: &[f64]| {
            let mut ok = true;
            for (((x, s), lo), hi) in run.iter().zip(&scale).zip(&lo).zip(&hi) {
                let y = x * s;
                ok &= (y >= *lo) & (y <= *hi);
            }
            ok
        };
        let runs = values.chunks_exact(period);
        let tail = runs.remainder();
        runs.fold(true, |ok, run| ok & within(run)) & within(tail)
    }

    /// Checked FK: validates `q` (see [`Robot::check_joints`]) and returns the tool pose.
    pub fn fk(&self, q: &[f64], opts: &FkOptions) -> Result<Transform> {
        Ok(self.check_joints(q, opts)?.fk())
    }

    /// Checked FK with every frame (see [`JointVector::fk_frames`]).
    pub fn fk_frames(&self, q: &[f64], opts: &FkOptions) -> Result<(Transform, Vec<Transform>)> {
        Ok(self.check_joints(q, opts)?.fk_frames())
    }
}

/// One joint vector that passed [`Robot::check_joints`] for its robot: right
/// length, finite, within limits when they were checked. Revolute values are
/// in the request's angle unit (the scale to rad is carried along),
/// prismatic ones in the model's length unit.
#[derive(Clone, Copy, Debug)]
pub struct JointVector<'a> {
    robot: &'a Robot,
    q: &'a [f64],
    angle_scale: f64,
}

impl<'a> JointVector<'a> {
    pub(crate) fn new(robot: &'a Robot, q: &'a [f64], angle_scale: f64) -> Self {
        Self {
            robot,
            q,
            angle_scale,
        }
    }

    /// The values as given.
    pub fn values(&self) -> &'a [f64] {
        self.q
    }

    /// The robot they were checked for.
    pub fn robot(&self) -> &'a Robot {
        self.robot
    }

    /// Factor from the values' angle unit to rad (1 for rad, π/180 for deg).
    pub fn angle_scale(&self) -> f64 {
        self.angle_scale
    }

    /// World pose of the tool tip, `base · A_1 ⋯ A_n · tool`. Allocates nothing.
    pub fn fk(&self) -> Transform {
        self.robot.chain().forward(self.q, self.angle_scale)
    }

    /// The tool pose and every frame: `frames[0]` is the base frame
    /// `^world T_0`, `frames[i]` the frame after DH row `i` (the last is the
    /// flange).
    pub fn fk_frames(&self) -> (Transform, Vec<Transform>) {
        self.robot.chain().forward_frames(self.q, self.angle_scale)
    }

    /// The tool pose, and every frame when `frames` is set: the one single-FK
    /// entry point that every front door and the CLI call.
    pub fn fk_with_frames(&self, frames: bool) -> (Transform, Option<Vec<Transform>>) {
        if frames {
            let (tool, all) = self.fk_frames();
            (tool, Some(all))
        } else {
            (self.fk(), None)
        }
    }
}

/// Many configurations that all passed [`Robot::check_batch`], back to back.
#[derive(Clone, Copy, Debug)]
pub struct JointBatch<'a> {
    robot: &'a Robot,
    values: &'a [f64],
    count: usize,
    angle_scale: f64,
}

impl<'a> JointBatch<'a> {
    pub(crate) fn new(robot: &'a Robot, values: &'a [f64], count: usize, angle_scale: f64) -> Self {
        Self {
            robot,
            values,
            count,
            angle_scale,
        }
    }

    /// Number of configurations.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Tool poses into `out` (one per configuration, up to `out.len()`), by
    /// the vectorised batch path. Allocates nothing.
    pub fn fk_into(&self, out: &mut [Transform]) {
        self.robot
            .chain()
            .forward_batch(self.values, self.angle_scale, out);
    }

    /// Each configuration as the joint vector it was checked as, in order
    /// (each was validated once, by [`Robot::check_batch`]).
    pub fn vectors(&self) -> impl ExactSizeIterator<Item = JointVector<'a>> + 'a {
        let (robot, scale, values) = (self.robot, self.angle_scale, self.values);
        let dof = robot.dof();
        (0..self.count).map(move |i| {
            let q = values.get(i * dof..(i + 1) * dof).unwrap_or(&[]);
            JointVector::new(robot, q, scale)
        })
    }

    /// Tool poses, in order.
    pub fn fk(&self) -> Vec<Transform> {
        let mut out = vec![Transform::IDENTITY; self.count];
        self.fk_into(&mut out);
        out
    }

    /// Tool poses, in order, in `format`: transforms for `full`, else the
    /// compact numbers written by the batch kernel straight into the one
    /// vector of the answer (the same numbers, bit for bit, as
    /// [`PoseFormat::pack`] of [`JointBatch::fk`]).
    pub fn fk_as(&self, format: PoseFormat) -> BatchPoses {
        let Some(layout) = format.layout() else {
            return BatchPoses::Full(self.fk());
        };
        let chain = self.robot.chain();
        let out = chain.forward_batch_packed_vec(self.values, self.count, self.angle_scale, layout);
        match layout {
            PackedLayout::Matrix12 => BatchPoses::Matrix(out),
            PackedLayout::Position => BatchPoses::Position(out),
        }
    }
}

/// The interval `[lo, hi]` a joint's value times `scale` must lie in to
/// pass [`Robot::check_value`]: `[scale, lo, hi]`, with `scale` the request's
/// to-rad factor for a revolute joint (1 otherwise), the magnitude bound and,
/// when checked, the joint's limits. NaN and ±∞ fall outside every such
/// interval.
#[inline]
fn bounds(j: &Joint, to_rad: f64, check_limits: bool) -> [f64; 3] {
    let (scale, max) = match j.kind {
        JointKind::Revolute => (to_rad, MAX_REVOLUTE_RAD),
        JointKind::Prismatic => (1.0, MAX_MAGNITUDE),
        // Not a movable joint; checked as finite (and limits) only.
        JointKind::Fixed => (1.0, f64::MAX),
    };
    let (lo, hi) = j.limits.filter(|_| check_limits).unwrap_or((-max, max));
    [scale, lo.max(-max), hi.min(max)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ModelLimits;

    /// A batch in a compact format holds exactly the numbers of the
    /// transforms packed afterwards (35 configurations: four blocks and a tail).
    #[test]
    fn a_batch_in_a_format_is_the_packed_transforms() {
        let robot = Robot::from_json(
            br#"{"name": "three", "convention": "modified", "links": [
                {"a": 0, "alpha": 0, "d": 0.3, "theta": 0, "joint": "revolute"},
                {"a": 0.2, "alpha": 1.5707963267948966, "d": 0, "theta": 0, "joint": "revolute"},
                {"a": 0.4, "alpha": 0, "d": 0.1, "theta": 0, "joint": "prismatic"}]}"#,
            &ModelLimits::default(),
        )
        .unwrap();
        let values: Vec<f64> = (0..35 * 3).map(|i| (i as f64 * 0.37).sin()).collect();
        let lens = vec![3u32; 35];
        let batch = robot
            .check_batch(&values, &lens, &FkOptions::default())
            .unwrap();
        let poses = batch.fk();
        assert_eq!(
            batch.fk_as(PoseFormat::Full),
            BatchPoses::Full(poses.clone())
        );
        for format in [PoseFormat::Matrix, PoseFormat::Position] {
            let packed = batch.fk_as(format);
            assert_eq!((packed.format(), packed.len()), (format, 35));
            let (BatchPoses::Matrix(v) | BatchPoses::Position(v)) = &packed else {
                panic!("{format:?} answered as transforms");
            };
            let expected = format.pack(poses.iter());
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(v), bits(&expected), "{format:?}");
        }
    }

    /// The one-pass batch check accepts exactly the values the per-value
    /// check accepts: every value at, just inside and just outside each
    /// bound, non-finite ones, in both angle units, limits checked or not.
    #[test]
    fn the_batch_pass_agrees_with_the_per_value_check() {
        let robot = Robot::from_json(
            br#"{"name": "two", "convention": "standard", "links": [
            {"joint": "revolute", "a": 0.4, "alpha": 0, "d": 0, "theta": 0, "limits": [-1.5, 2.5]},
            {"joint": "prismatic", "a": 0, "alpha": 0, "d": 0.1, "theta": 0, "limits": [0, 0.2]},
            {"joint": "revolute", "a": 0.1, "alpha": 0, "d": 0, "theta": 0}
        ]}"#,
            &ModelLimits::default(),
        )
        .unwrap();
        let deg = 180.0 / std::f64::consts::PI;
        let mut xs = vec![
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e300,
            -1e300,
        ];
        for b in [
            -1.5,
            2.5,
            0.0,
            0.2,
            MAX_REVOLUTE_RAD,
            -MAX_REVOLUTE_RAD,
            MAX_MAGNITUDE,
        ] {
            for v in [b, b * deg] {
                xs.extend([v, v.next_up(), v.next_down()]);
            }
        }
        let mut agreed = 0;
        for unit in [AngleUnit::Rad, AngleUnit::Deg] {
            for check_limits in [true, false] {
                let opts = FkOptions::new(Some(unit), Some(check_limits));
                for (j, joint) in robot.joints().iter().enumerate() {
                    for &x in &xs {
                        let mut q = [0.0, 0.1, 0.0];
                        q[j] = x;
                        let slow = robot.check_value(x, joint, &opts).is_none();
                        assert_eq!(
                            robot.batch_within_bounds(&q, &opts),
                            slow,
                            "joint {j} x {x:e} {unit:?} {check_limits}"
                        );
                        assert_eq!(
                            robot.check_joints(&q, &opts).is_ok(),
                            slow,
                            "one configuration: joint {j} x {x:e} {unit:?} {check_limits}"
                        );
                        // Among 10 good configurations: in a whole run of
                        // eight (position 3) and in the tail (position 9).
                        for at in [3, 9] {
                            let mut batch = [0.0, 0.1, 0.0].repeat(11);
                            batch[3 * at + j] = x;
                            let fast = robot.batch_within_bounds(&batch, &opts);
                            assert_eq!(fast, slow, "joint {j} x {x:e} at {at}");
                        }
                        agreed += usize::from(slow);
                    }
                }
            }
        }
        // Both verdicts occur.
        assert!(agreed > 0 && agreed < 4 * 3 * xs.len());
    }
}
