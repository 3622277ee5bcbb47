//! The public face of a serial chain: [`Chain`], which compiles its table
//! once ([`crate::program`]) and evaluates it on the kernel picked at run time
//! ([`crate::eval`]). The row types it is built from live in [`crate::dh`].
//!
//! Depends on [`crate::dh`], [`crate::program`], [`crate::eval`],
//! [`crate::batch_out`], [`crate::kernel`] and [`crate::transform`].

use std::mem::MaybeUninit;

use crate::batch_out::{Matrix12Out, PackedLayout, PositionOut};
use crate::dh::{Convention, DhRow, JointKind};
use crate::eval;
use crate::kernel::Kernel;
use crate::program::{self, Program};
use crate::transform::Transform;

/// A validated-elsewhere, compiled kinematic chain.
///
/// Build it with [`Chain::new`]; evaluate with [`Chain::forward`] (tool pose),
/// [`Chain::forward_frames`] (every frame) or [`Chain::forward_batch`].
/// Joint values: one per movable row in table order; rad for revolute joints
/// (times the `angle_scale` passed to the evaluators), the model's length unit
/// for prismatic joints.
///
/// `Chain::new` specialises the table once: constants folded together, each
/// step classified by which of its entries are 0 or ±1 (see
/// `crate::program`), so evaluation does only the arithmetic the table needs.
#[derive(Clone, Debug)]
pub struct Chain {
    convention: Convention,
    rows: Vec<DhRow>,
    base: Transform,
    tool: Option<Transform>,
    program: Program,
}

impl Chain {
    /// Compiles a chain from its rows, base (world ← frame 0) and tool (flange ← tool tip).
    /// An identity tool is dropped ([`Chain::tool`] is then `None`).
    ///
    /// ```
    /// use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};
    ///
    /// let row = |kind, a, d| DhRow { kind, a, alpha: 0.0, d, theta: 0.0 };
    /// let rows = [
    ///     row(JointKind::Revolute, 0.4, 0.0),
    ///     row(JointKind::Fixed, 0.1, 0.0), // a constant offset, no joint variable
    ///     row(JointKind::Prismatic, 0.0, 0.2),
    /// ];
    /// let base = Transform::translation(0.0, 0.0, 1.0); // on a 1 m pedestal
    /// let tool = Transform::translation(0.0, 0.0, 0.05); // 5 cm along the flange z
    /// let chain = Chain::new(Convention::Standard, &rows, base, Some(tool));
    /// assert_eq!((chain.dof(), chain.rows()), (2, 3));
    /// assert!(chain.tool().is_some());
    ///
    /// // Home pose: x = 0.4 + 0.1, z = 1 + 0.2 + 0.05.
    /// let [x, y, z] = chain.forward(&[0.0, 0.0], 1.0).position();
    /// assert!((x - 0.5).abs() < 1e-12 && y.abs() < 1e-12 && (z - 1.25).abs() < 1e-12);
    ///
    /// let bare = Chain::new(Convention::Standard, &rows, base, Some(Transform::IDENTITY));
    /// assert!(bare.tool().is_none());
    /// ```
    pub fn new(
        convention: Convention,
        rows: &[DhRow],
        base: Transform,
        tool: Option<Transform>,
    ) -> Chain {
        let tool = tool.filter(|t| *t != Transform::IDENTITY);
        Chain {
            convention,
            rows: rows.to_vec(),
            base,
            tool,
            program: program::compile(convention, rows, &base, tool.as_ref()),
        }
    }

    /// Number of movable joints.
    pub fn dof(&self) -> usize {
        self.program.steps.len()
    }

    /// Number of DH rows (movable and fixed).
    pub fn rows(&self) -> usize {
        self.rows.len()
    }

    /// The DH convention of the table.
    pub fn convention(&self) -> Convention {
        self.convention
    }

    /// Kind of each movable joint, in order.
    pub fn joint_kinds(&self) -> impl Iterator<Item = JointKind> + '_ {
        self.rows
            .iter()
            .map(|r| r.kind)
            .filter(|k| *k != JointKind::Fixed)
    }

    /// The rows as compiled, in table order (angles in rad).
    pub fn dh_rows(&self) -> impl ExactSizeIterator<Item = DhRow> + '_ {
        self.rows.iter().copied()
    }

    /// The base transform (world ← frame 0).
    pub fn base(&self) -> &Transform {
        &self.base
    }

    /// The tool transform (flange ← tool tip), if it is not the identity.
    pub fn tool(&self) -> Option<&Transform> {
        self.tool.as_ref()
    }

    /// How many of the compiled steps are aligned ones (see `crate::program`),
    /// out of [`Chain::dof`]: the rest run the general product. For tests and
    /// benchmarks.
    pub fn aligned_steps(&self) -> usize {
        self.program
            .steps
            .iter()
            .filter(|s| s.kind != program::GENERAL)
            .count()
    }

    /// World pose of the tool tip, `base · A_1 ⋯ A_n · tool`, for joint values `q`
    /// (revolute values are multiplied by `angle_scale`, e.g. π/180 for degrees),
    /// on the [best kernel](Kernel::best) of this CPU.
    ///
    /// Unchecked: the caller guarantees `q.len() == self.dof()` and finite values;
    /// missing values count as 0 and extra ones are ignored. Allocates nothing.
    ///
    /// The result is the textbook product of the link matrices
    /// ([`link_transform`](crate::link_transform)):
    ///
    /// ```
    /// use std::f64::consts::{FRAC_PI_2, PI};
    /// use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform, link_transform};
    ///
    /// let rows = [
    ///     DhRow { kind: JointKind::Revolute, a: 0.0, alpha: 0.0, d: 0.3, theta: 0.0 },
    ///     DhRow { kind: JointKind::Revolute, a: 0.0, alpha: -FRAC_PI_2, d: 0.0, theta: 0.0 },
    ///     DhRow { kind: JointKind::Revolute, a: 0.4, alpha: 0.0, d: 0.0, theta: 0.0 },
    /// ];
    /// let base = Transform::translation(0.1, 0.0, 0.0);
    /// let chain = Chain::new(Convention::Modified, &rows, base, None);
    ///
    /// let q_deg = [30.0, -45.0, 60.0];
    /// let pose = chain.forward(&q_deg, PI / 180.0);
    ///
    /// let mut plain = base;
    /// for (row, q) in rows.iter().zip(q_deg) {
    ///     plain = plain * link_transform(Convention::Modified, row, q.to_radians());
    /// }
    /// assert!(pose.max_abs_diff(&plain) < 1e-12);
    /// assert!(pose.rigidity_error() < 1e-12);
    /// ```
    #[inline]
    pub fn forward(&self, q: &[f64], angle_scale: f64) -> Transform {
        // SAFETY: `Kernel::best` only returns a kernel this CPU supports.
        unsafe { eval::forward_on(Kernel::best(), &self.program, q, angle_scale) }
    }

    /// [`Chain::forward`] on a given kernel (the portable one if the CPU lacks it).
    pub fn forward_with(&self, kernel: Kernel, q: &[f64], angle_scale: f64) -> Transform {
        // SAFETY: `or_portable` only returns a kernel this CPU supports.
        unsafe { eval::forward_on(kernel.or_portable(), &self.program, q, angle_scale) }
    }

    /// Like [`Chain::forward`], and calls `frame` with `^world T_i` for every frame
    /// `i = 0..=rows` (0 is the base frame, `rows` the flange) in order.
    /// Returns the tool pose. Allocates nothing.
    pub fn forward_frames_into(
        &self,
        q: &[f64],
        angle_scale: f64,
        frame: &mut dyn FnMut(&Transform),
    ) -> Transform {
        self.forward_frames_into_with(Kernel::best(), q, angle_scale, frame)
    }

    /// [`Chain::forward_frames_into`] on a given kernel (the portable one if the CPU lacks it).
    pub fn forward_frames_into_with(
        &self,
        kernel: Kernel,
        q: &[f64],
        angle_scale: f64,
        frame: &mut dyn FnMut(&Transform),
    ) -> Transform {
        let mut sink = eval::Sink::Burst(eval::Burst::new(frame));
        // SAFETY: `or_portable` only returns a kernel this CPU supports.
        unsafe {
            eval::forward_frames_on(
                kernel.or_portable(),
                &self.program,
                q,
                angle_scale,
                &mut sink,
            )
        }
    }

    /// Like [`Chain::forward`], and writes `^world T_i` for every frame
    /// `i = 0..=rows` into `frames[i]` (0 is the base frame, `rows` the flange;
    /// frames beyond the slice's end are not written). Returns the tool pose.
    /// No callback per frame, so cheaper than [`Chain::forward_frames_into`].
    /// Allocates nothing.
    pub fn forward_frames_to(
        &self,
        q: &[f64],
        angle_scale: f64,
        frames: &mut [Transform],
    ) -> Transform {
        self.forward_frames_to_with(Kernel::best(), q, angle_scale, frames)
    }

    /// [`Chain::forward_frames_to`] on a given kernel (the portable one if the CPU lacks it).
    pub fn forward_frames_to_with(
        &self,
        kernel: Kernel,
        q: &[f64],
        angle_scale: f64,
        frames: &mut [Transform],
    ) -> Transform {
        let mut sink = eval::Sink::Slice(eval::SliceSink::new(frames));
        // SAFETY: `or_portable` only returns a kernel this CPU supports.
        unsafe {
            eval::forward_frames_on(
                kernel.or_portable(),
                &self.program,
                q,
                angle_scale,
                &mut sink,
            )
        }
    }

    /// Tool pose and every frame (see [`Chain::forward_frames_to`]).
    pub fn forward_frames(&self, q: &[f64], angle_scale: f64) -> (Transform, Vec<Transform>) {
        self.forward_frames_with(Kernel::best(), q, angle_scale)
    }

    /// [`Chain::forward_frames`] on a given kernel (the portable one if the CPU lacks it).
    pub fn forward_frames_with(
        &self,
        kernel: Kernel,
        q: &[f64],
        angle_scale: f64,
    ) -> (Transform, Vec<Transform>) {
        let mut frames = vec![Transform::IDENTITY; self.rows.len() + 1];
        let tool = self.forward_frames_to_with(kernel, q, angle_scale, &mut frames);
        (tool, frames)
    }

    /// Tool poses for many configurations at once, on the [best kernel](Kernel::best).
    /// `q` holds the configurations back to back (`dof` values each; a trailing
    /// partial configuration is ignored), and `out` receives one pose per
    /// configuration (up to its length; a chain without movable joints fills all
    /// of `out` with its one pose). Structure-of-arrays over blocks of 8 poses.
    /// Unchecked like [`Chain::forward`]. Allocates nothing.
    pub fn forward_batch(&self, q: &[f64], angle_scale: f64, out: &mut [Transform]) {
        self.forward_batch_with(Kernel::best(), q, angle_scale, out)
    }

    /// [`Chain::forward_batch`] on a given kernel (the portable one if the CPU lacks it).
    pub fn forward_batch_with(
        &self,
        kernel: Kernel,
        q: &[f64],
        angle_scale: f64,
        out: &mut [Transform],
    ) {
        // SAFETY: `or_portable` only returns a kernel this CPU supports.
        unsafe { eval::forward_batch_on(kernel.or_portable(), &self.program, q, angle_scale, out) }
    }

    /// [`Chain::forward_batch`] with each pose written as the numbers of
    /// `layout`, back to back in `out` (one pose per `layout.stride()`
    /// numbers, up to `out.len() / stride`; a trailing partial pose is left
    /// alone), straight from the kernel: the same numbers, bit for bit, as
    /// the transforms [`Chain::forward_batch`] gives. Allocates nothing.
    ///
    /// ```
    /// use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, PackedLayout, Transform};
    ///
    /// let row = |a: f64| DhRow { kind: JointKind::Revolute, a, alpha: 0.0, d: 0.0, theta: 0.0 };
    /// let chain = Chain::new(Convention::Standard, &[row(1.0), row(0.5)], Transform::IDENTITY, None);
    /// let q = [0.0, 0.0, 0.3, -0.2, 1.0, 0.5]; // three configurations of two joints
    /// let mut positions = [0.0; 9];
    /// chain.forward_batch_packed(&q, 1.0, PackedLayout::Position, &mut positions);
    /// assert_eq!(positions[..3], [1.5, 0.0, 0.0]); // stretched along x (lengths in the table's unit)
    /// let mut poses = [Transform::IDENTITY; 3];
    /// chain.forward_batch(&q, 1.0, &mut poses);
    /// assert_eq!(positions[6..], poses[2].translation);
    /// ```
    pub fn forward_batch_packed(
        &self,
        q: &[f64],
        angle_scale: f64,
        layout: PackedLayout,
        out: &mut [f64],
    ) {
        self.forward_batch_packed_with(Kernel::best(), q, angle_scale, layout, out)
    }

    /// [`Chain::forward_batch_packed`] on a given kernel (the portable one if the CPU lacks it).
    pub fn forward_batch_packed_with(
        &self,
        kernel: Kernel,
        q: &[f64],
        angle_scale: f64,
        layout: PackedLayout,
        out: &mut [f64],
    ) {
        let out: *mut [f64] = out;
        // SAFETY: `MaybeUninit<f64>` has the layout of `f64`, and the
        // evaluators only ever write initialised doubles through it, so
        // `out` stays initialised.
        let out = unsafe { &mut *(out as *mut [MaybeUninit<f64>]) };
        self.packed_into(kernel, q, angle_scale, layout, out);
    }

    /// [`Chain::forward_batch_packed`] into a new vector of `count` poses
    /// (fewer if `q` holds fewer configurations), its memory written once,
    /// by the kernel: nothing is zeroed first.
    ///
    /// ```
    /// use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, PackedLayout, Transform};
    ///
    /// let row = DhRow { kind: JointKind::Prismatic, a: 0.0, alpha: 0.0, d: 0.1, theta: 0.0 };
    /// let chain = Chain::new(Convention::Standard, &[row], Transform::IDENTITY, None);
    /// let z = chain.forward_batch_packed_vec(&[0.0, 0.5], 2, 1.0, PackedLayout::Position);
    /// assert_eq!(z, [0.0, 0.0, 0.1, 0.0, 0.0, 0.6]);
    /// ```
    pub fn forward_batch_packed_vec(
        &self,
        q: &[f64],
        count: usize,
        angle_scale: f64,
        layout: PackedLayout,
    ) -> Vec<f64> {
        let dof = self.dof();
        // A chain without joints has `count` poses whatever `q` holds.
        let count = q.len().checked_div(dof).map_or(count, |n| count.min(n));
        let len = count * layout.stride();
        let mut out = Vec::with_capacity(len);
        self.packed_into(
            Kernel::best(),
            q,
            angle_scale,
            layout,
            &mut out.spare_capacity_mut()[..len],
        );
        // SAFETY: the evaluator wrote every pose of `out` whole: poses
        // `0..min(q.len() / dof, count)` = `0..count`, or all `count` poses of a
        // chain without joints, `stride` numbers each, so `0..len` is initialised.
        unsafe { out.set_len(len) };
        out
    }

    /// The packed batch into `out`: every pose `0..min(configurations,
    /// out.len() / stride)` is written whole (all of them for a chain
    /// without joints), nothing else.
    fn packed_into(
        &self,
        kernel: Kernel,
        q: &[f64],
        angle_scale: f64,
        layout: PackedLayout,
        out: &mut [MaybeUninit<f64>],
    ) {
        let (kernel, p) = (kernel.or_portable(), &self.program);
        // SAFETY: `or_portable` only returns a kernel this CPU supports.
        unsafe {
            match layout {
                PackedLayout::Matrix12 => {
                    eval::forward_batch_on(kernel, p, q, angle_scale, &mut Matrix12Out(out))
                }
                PackedLayout::Position => {
                    eval::forward_batch_on(kernel, p, q, angle_scale, &mut PositionOut(out))
                }
            }
        }
    }
}
