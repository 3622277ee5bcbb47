//! A compiled serial chain: DH rows with everything that does not depend on the
//! joint values precomputed, and the forward-kinematics products over it.
#![allow(
    clippy::needless_range_loop,
    reason = "matrix code reads best with explicit row/column indices"
)]

use crate::kernel::Kernel;
use crate::sincos::{self, madd, needs_std, sincos_poly_impl};
use crate::transform::Transform;

/// Which Denavit–Hartenberg convention a table is written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Convention {
    /// Standard (distal): `A_i = Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`.
    Standard,
    /// Modified (proximal, Craig): `A_i = Rx(α_{i-1})·Tx(a_{i-1})·Rz(θ_i)·Tz(d_i)`;
    /// row `i` holds `α_{i-1}, a_{i-1}, θ_i, d_i`.
    Modified,
}

/// The kind of joint a DH row describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JointKind {
    /// The joint value (rad) is added to θ.
    Revolute,
    /// The joint value (length unit) is added to d.
    Prismatic,
    /// No joint variable: a constant frame written as a table row.
    Fixed,
}

/// One DH row in internal units: angles in rad, lengths in the model's length unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DhRow {
    /// Joint kind.
    pub kind: JointKind,
    /// Link length `a` (standard: `a_i`; modified: `a_{i-1}`).
    pub a: f64,
    /// Link twist `α` in rad (standard: `α_i`; modified: `α_{i-1}`).
    pub alpha: f64,
    /// Link offset `d` (the zero position for a prismatic joint).
    pub d: f64,
    /// Joint angle `θ` in rad (the zero offset for a revolute joint).
    pub theta: f64,
}

/// The homogeneous matrix of one DH row for joint value `q` (rad for revolute,
/// length unit for prismatic, ignored for fixed), computed plainly with `std`
/// trigonometry and generic products: the textbook definition, which the fast
/// paths of [`Chain`] are tested against.
pub fn link_transform(convention: Convention, row: &DhRow, q: f64) -> Transform {
    let (theta, d) = match row.kind {
        JointKind::Revolute => (row.theta + q, row.d),
        JointKind::Prismatic => (row.theta, row.d + q),
        JointKind::Fixed => (row.theta, row.d),
    };
    match convention {
        Convention::Standard => {
            Transform::rot_z(theta)
                * Transform::translation(0.0, 0.0, d)
                * Transform::translation(row.a, 0.0, 0.0)
                * Transform::rot_x(row.alpha)
        }
        Convention::Modified => {
            Transform::rot_x(row.alpha)
                * Transform::translation(row.a, 0.0, 0.0)
                * Transform::rot_z(theta)
                * Transform::translation(0.0, 0.0, d)
        }
    }
}

/// Per-row constants, computed once.
#[derive(Clone, Copy, Debug)]
struct Link {
    kind: JointKind,
    a: f64,
    alpha: f64,
    d: f64,
    theta: f64,
    ca: f64,
    sa: f64,
    /// cos/sin of θ for prismatic and fixed rows.
    ct: f64,
    st: f64,
}

/// A validated-elsewhere, compiled kinematic chain.
///
/// Build it with [`Chain::new`]; evaluate with [`Chain::forward`] (tool pose),
/// [`Chain::forward_frames`] (every frame) or [`Chain::forward_batch`].
/// Joint values: one per movable row in table order; rad for revolute joints
/// (times the `angle_scale` passed to the evaluators), the model's length unit
/// for prismatic joints.
#[derive(Clone, Debug)]
pub struct Chain {
    convention: Convention,
    links: Vec<Link>,
    /// Index into `links` of each movable row.
    movable: Vec<usize>,
    base: Transform,
    tool: Option<Transform>,
}

/// Poses evaluated together in the batch path (structure of arrays).
const LANES: usize = 8;

impl Chain {
    /// Compiles a chain from its rows, base (world ← frame 0) and tool (flange ← tool tip).
    pub fn new(
        convention: Convention,
        rows: &[DhRow],
        base: Transform,
        tool: Option<Transform>,
    ) -> Chain {
        let links: Vec<Link> = rows
            .iter()
            .map(|r| {
                let (sa, ca) = r.alpha.sin_cos();
                let (st, ct) = r.theta.sin_cos();
                Link {
                    kind: r.kind,
                    a: r.a,
                    alpha: r.alpha,
                    d: r.d,
                    theta: r.theta,
                    ca,
                    sa,
                    ct,
                    st,
                }
            })
            .collect();
        let movable = rows
            .iter()
            .enumerate()
            .filter(|(_, r)| r.kind != JointKind::Fixed)
            .map(|(i, _)| i)
            .collect();
        Chain {
            convention,
            links,
            movable,
            base,
            tool: tool.filter(|t| *t != Transform::IDENTITY),
        }
    }

    /// Number of movable joints.
    pub fn dof(&self) -> usize {
        self.movable.len()
    }

    /// Number of DH rows (movable and fixed).
    pub fn rows(&self) -> usize {
        self.links.len()
    }

    /// The DH convention of the table.
    pub fn convention(&self) -> Convention {
        self.convention
    }

    /// Kind of each movable joint, in order.
    pub fn joint_kinds(&self) -> impl Iterator<Item = JointKind> + '_ {
        self.movable.iter().map(|&i| self.links[i].kind)
    }

    /// `(cos θ, sin θ, d)` of row `l`. For a revolute row `sv, cv` are the sine and
    /// cosine of `θ0 + q`; for a prismatic row `v` is the joint value `q`.
    #[inline(always)]
    fn row_values(l: &Link, v: f64, sv: f64, cv: f64) -> (f64, f64, f64) {
        match l.kind {
            JointKind::Revolute => (cv, sv, l.d),
            JointKind::Prismatic => (l.ct, l.st, l.d + v),
            JointKind::Fixed => (l.ct, l.st, l.d),
        }
    }

    /// The rows as compiled, in table order (angles in rad).
    pub fn dh_rows(&self) -> impl ExactSizeIterator<Item = DhRow> + '_ {
        self.links.iter().map(|l| DhRow {
            kind: l.kind,
            a: l.a,
            alpha: l.alpha,
            d: l.d,
            theta: l.theta,
        })
    }

    /// The base transform (world ← frame 0).
    pub fn base(&self) -> &Transform {
        &self.base
    }

    /// The tool transform (flange ← tool tip), if it is not the identity.
    pub fn tool(&self) -> Option<&Transform> {
        self.tool.as_ref()
    }

    /// World pose of the tool tip, `base · A_1 ⋯ A_n · tool`, for joint values `q`
    /// (revolute values are multiplied by `angle_scale`, e.g. π/180 for degrees),
    /// on the [best kernel](Kernel::best) of this CPU.
    ///
    /// Unchecked: the caller guarantees `q.len() == self.dof()` and finite values;
    /// missing values count as 0 and extra ones are ignored. Allocates nothing.
    #[inline]
    pub fn forward(&self, q: &[f64], angle_scale: f64) -> Transform {
        // One feature check, then straight into the kernel (this is the hot path).
        #[cfg(target_arch = "x86_64")]
        if Kernel::Avx2Fma.is_supported() {
            // SAFETY: the CPU supports avx2 and fma (checked just above).
            return unsafe { self.forward_avx2(q, angle_scale) };
        }
        self.forward_impl::<false>(q, angle_scale)
    }

    /// [`Chain::forward`] on a given kernel (the portable one if the CPU lacks it).
    pub fn forward_with(&self, kernel: Kernel, q: &[f64], angle_scale: f64) -> Transform {
        match kernel.or_portable() {
            Kernel::Portable => self.forward_impl::<false>(q, angle_scale),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `or_portable` returned Avx2Fma, so the CPU supports avx2 and fma.
            Kernel::Avx2Fma => unsafe { self.forward_avx2(q, angle_scale) },
            #[cfg(not(target_arch = "x86_64"))]
            Kernel::Avx2Fma => self.forward_impl::<false>(q, angle_scale),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn forward_avx2(&self, q: &[f64], angle_scale: f64) -> Transform {
        self.forward_impl::<true>(q, angle_scale)
    }

    /// The single-pose product on a column-major 4×4 (columns x, y, z, p; lane 3
    /// unused), so each step is a handful of 4-wide vector operations.
    #[inline(always)]
    fn forward_impl<const FMA: bool>(&self, q: &[f64], angle_scale: f64) -> Transform {
        const SMALL: usize = 8;
        let n = self.movable.len();
        // Joint angles (θ0 + q) and their sines and cosines, computed together.
        let mut x = [0.0f64; SMALL];
        let mut sv = [0.0f64; SMALL];
        let mut cv = [1.0f64; SMALL];
        let small = n <= SMALL;
        if small {
            for ((dst, &i), src) in x.iter_mut().zip(&self.movable).zip(q) {
                let l = &self.links[i];
                *dst = match l.kind {
                    JointKind::Revolute => madd::<FMA>(*src, angle_scale, l.theta),
                    _ => *src,
                };
            }
            for k in 0..SMALL {
                (sv[k], cv[k]) = sincos_poly_impl::<FMA>(x[k]);
            }
            for k in 0..SMALL {
                if needs_std(x[k]) {
                    (sv[k], cv[k]) = x[k].sin_cos();
                }
            }
        }
        let mut c = to_cols(&self.base);
        let mut j = 0;
        let mut qi = q.iter();
        for l in &self.links {
            let (ct, st, d) = match l.kind {
                JointKind::Fixed => (l.ct, l.st, l.d),
                JointKind::Revolute => {
                    let (s, co) = if small {
                        (sv[j], cv[j])
                    } else {
                        let v =
                            madd::<FMA>(qi.next().copied().unwrap_or(0.0), angle_scale, l.theta);
                        if needs_std(v) {
                            v.sin_cos()
                        } else {
                            sincos_poly_impl::<FMA>(v)
                        }
                    };
                    j += 1;
                    (co, s, l.d)
                }
                JointKind::Prismatic => {
                    let v = if small {
                        x[j]
                    } else {
                        qi.next().copied().unwrap_or(0.0)
                    };
                    j += 1;
                    (l.ct, l.st, l.d + v)
                }
            };
            if small {
                let _ = qi.next();
            }
            apply_cols::<FMA>(self.convention, &mut c, l, ct, st, d);
        }
        let t = from_cols(&c);
        match &self.tool {
            Some(tool) => t.compose(tool),
            None => t,
        }
    }

    /// Like [`Chain::forward`], and calls `frame` with `^world T_i` for every frame
    /// `i = 0..=rows` (0 is the base frame, `rows` the flange) in order.
    /// Returns the tool pose. Uses `std` trigonometry.
    pub fn forward_frames_into(
        &self,
        q: &[f64],
        angle_scale: f64,
        frame: &mut dyn FnMut(&Transform),
    ) -> Transform {
        let mut c = to_cols(&self.base);
        frame(&self.base);
        let mut qi = q.iter();
        for l in &self.links {
            let v = match l.kind {
                JointKind::Fixed => 0.0,
                JointKind::Revolute => l.theta + qi.next().copied().unwrap_or(0.0) * angle_scale,
                JointKind::Prismatic => qi.next().copied().unwrap_or(0.0),
            };
            let (sv, cv) = v.sin_cos();
            let (ct, st, d) = Self::row_values(l, v, sv, cv);
            apply_cols::<false>(self.convention, &mut c, l, ct, st, d);
            frame(&from_cols(&c));
        }
        let t = from_cols(&c);
        match &self.tool {
            Some(tool) => t.compose(tool),
            None => t,
        }
    }

    /// Tool pose and every frame (see [`Chain::forward_frames_into`]).
    pub fn forward_frames(&self, q: &[f64], angle_scale: f64) -> (Transform, Vec<Transform>) {
        let mut frames = Vec::with_capacity(self.links.len() + 1);
        let tool = self.forward_frames_into(q, angle_scale, &mut |t| frames.push(*t));
        (tool, frames)
    }

    /// Tool poses for many configurations at once, on the [best kernel](Kernel::best).
    /// `q` holds the configurations back to back (`dof` values each; a trailing
    /// partial configuration is ignored), and `out` receives one pose per
    /// configuration (up to its length). Structure-of-arrays over groups of 8
    /// poses. Unchecked like [`Chain::forward`]. Allocates nothing.
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
        match kernel.or_portable() {
            Kernel::Portable => self.forward_batch_generic::<false>(q, angle_scale, out),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `or_portable` returned Avx2Fma, so the CPU supports avx2 and fma.
            Kernel::Avx2Fma => unsafe { self.forward_batch_avx2(q, angle_scale, out) },
            #[cfg(not(target_arch = "x86_64"))]
            Kernel::Avx2Fma => self.forward_batch_generic::<false>(q, angle_scale, out),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn forward_batch_avx2(&self, q: &[f64], angle_scale: f64, out: &mut [Transform]) {
        self.forward_batch_generic::<true>(q, angle_scale, out)
    }

    #[inline(always)]
    fn forward_batch_generic<const FMA: bool>(
        &self,
        q: &[f64],
        angle_scale: f64,
        out: &mut [Transform],
    ) {
        let dof = self.movable.len();
        if dof == 0 {
            return;
        }
        let count = (q.len() / dof).min(out.len());
        let mut start = 0;
        while start < count {
            let lanes = (count - start).min(LANES);
            if lanes < LANES {
                for k in 0..lanes {
                    let i = start + k;
                    out[i] = self.forward_impl::<FMA>(&q[i * dof..(i + 1) * dof], angle_scale);
                }
                break;
            }
            self.batch_block::<FMA>(
                &q[start * dof..(start + LANES) * dof],
                angle_scale,
                dof,
                &mut out[start..start + LANES],
            );
            start += LANES;
        }
    }

    /// Eight poses in structure-of-arrays form: every scalar of the pose is a
    /// `[f64; 8]` so each step of the DH product is one vector operation.
    #[inline(always)]
    fn batch_block<const FMA: bool>(
        &self,
        q: &[f64],
        angle_scale: f64,
        dof: usize,
        out: &mut [Transform],
    ) {
        type V = [f64; LANES];
        let mut r = [[[0.0f64; LANES]; 3]; 3];
        let mut p = [[0.0f64; LANES]; 3];
        for i in 0..3 {
            for j in 0..3 {
                r[i][j] = [self.base.rotation[i][j]; LANES];
            }
            p[i] = [self.base.translation[i]; LANES];
        }
        // Row slices of the eight configurations (one bounds check each, here).
        let cfg: [&[f64]; LANES] =
            std::array::from_fn(|k| q.get(k * dof..(k + 1) * dof).unwrap_or(&[]));
        let mut j = 0;
        for l in &self.links {
            let mut ct: V = [l.ct; LANES];
            let mut st: V = [l.st; LANES];
            let mut d: V = [l.d; LANES];
            if l.kind != JointKind::Fixed {
                // Gather joint j of the eight configurations, then work on whole vectors.
                let mut x: V = [0.0; LANES];
                for k in 0..LANES {
                    x[k] = cfg[k].get(j).copied().unwrap_or(0.0);
                }
                j += 1;
                if l.kind == JointKind::Revolute {
                    for k in 0..LANES {
                        x[k] = madd::<FMA>(x[k], angle_scale, l.theta);
                    }
                    for k in 0..LANES {
                        (st[k], ct[k]) = sincos_poly_impl::<FMA>(x[k]);
                    }
                    if x.iter().any(|&v| sincos::needs_std(v)) {
                        for k in 0..LANES {
                            (st[k], ct[k]) = x[k].sin_cos();
                        }
                    }
                } else {
                    for k in 0..LANES {
                        d[k] = l.d + x[k];
                    }
                }
            }
            match self.convention {
                Convention::Standard => step_soa::<FMA, false>(&mut r, &mut p, l, &ct, &st, &d),
                Convention::Modified => step_soa::<FMA, true>(&mut r, &mut p, l, &ct, &st, &d),
            }
        }
        for (k, o) in out.iter_mut().enumerate().take(LANES) {
            let mut t = Transform::IDENTITY;
            for i in 0..3 {
                for jj in 0..3 {
                    t.rotation[i][jj] = r[i][jj][k];
                }
                t.translation[i] = p[i][k];
            }
            *o = match &self.tool {
                Some(tool) => t.compose(tool),
                None => t,
            };
        }
    }
}

/// Column-major copy of a transform: columns x, y, z of the rotation, then p; lane 3 is 0.
#[inline(always)]
fn to_cols(t: &Transform) -> [[f64; 4]; 4] {
    let r = &t.rotation;
    let p = &t.translation;
    [
        [r[0][0], r[1][0], r[2][0], 0.0],
        [r[0][1], r[1][1], r[2][1], 0.0],
        [r[0][2], r[1][2], r[2][2], 0.0],
        [p[0], p[1], p[2], 0.0],
    ]
}

#[inline(always)]
fn from_cols(c: &[[f64; 4]; 4]) -> Transform {
    Transform {
        rotation: [
            [c[0][0], c[1][0], c[2][0]],
            [c[0][1], c[1][1], c[2][1]],
            [c[0][2], c[1][2], c[2][2]],
        ],
        translation: [c[3][0], c[3][1], c[3][2]],
    }
}

/// The one DH step: one row `[x0, x1, x2, p]` of `[R | p]` (world ← frame i-1)
/// multiplied by the link matrix of `l` with the given `cos θ, sin θ, d`, giving
/// the same row of world ← frame i. Every evaluator (single pose, frames,
/// batch) is built from this function:
///
/// ```text
/// standard: A = [[ct, -st*ca,  st*sa, a*ct],     modified: A = [[   ct,    -st,   0,     a],
///                [st,  ct*ca, -ct*sa, a*st],                    [st*ca,  ct*ca, -sa, -sa*d],
///                [ 0,     sa,     ca,    d]]                    [st*sa,  ct*sa,  ca,  ca*d]]
/// ```
#[inline(always)]
#[allow(
    clippy::too_many_arguments,
    reason = "one row of a 3×4 block and one DH row, all scalars in registers"
)]
fn dh_row<const FMA: bool, const MODIFIED: bool>(
    l: &Link,
    ct: f64,
    st: f64,
    d: f64,
    x0: f64,
    x1: f64,
    x2: f64,
    p: f64,
) -> [f64; 4] {
    if MODIFIED {
        let u = madd::<FMA>(x1, l.ca, x2 * l.sa);
        let w = madd::<FMA>(x2, l.ca, -(x1 * l.sa));
        [
            madd::<FMA>(x0, ct, u * st),
            madd::<FMA>(u, ct, -(x0 * st)),
            w,
            madd::<FMA>(x0, l.a, madd::<FMA>(w, d, p)),
        ]
    } else {
        let x = madd::<FMA>(x0, ct, x1 * st);
        let y = madd::<FMA>(x1, ct, -(x0 * st));
        [
            x,
            madd::<FMA>(y, l.ca, x2 * l.sa),
            madd::<FMA>(x2, l.ca, -(y * l.sa)),
            madd::<FMA>(x, l.a, madd::<FMA>(x2, d, p)),
        ]
    }
}

/// Multiplies the column-major transform `c` in place by the link matrix of `l`
/// (the single-pose and frames paths): [`dh_row`] on each of the 4 lanes.
#[inline(always)]
fn apply_cols<const FMA: bool>(
    convention: Convention,
    c: &mut [[f64; 4]; 4],
    l: &Link,
    ct: f64,
    st: f64,
    d: f64,
) {
    match convention {
        Convention::Standard => apply_cols_as::<FMA, false>(c, l, ct, st, d),
        Convention::Modified => apply_cols_as::<FMA, true>(c, l, ct, st, d),
    }
}

#[inline(always)]
fn apply_cols_as<const FMA: bool, const MODIFIED: bool>(
    c: &mut [[f64; 4]; 4],
    l: &Link,
    ct: f64,
    st: f64,
    d: f64,
) {
    let [c0, c1, c2, p] = *c;
    let (mut n0, mut n1, mut n2, mut np) = ([0.0; 4], [0.0; 4], [0.0; 4], [0.0; 4]);
    for k in 0..4 {
        [n0[k], n1[k], n2[k], np[k]] =
            dh_row::<FMA, MODIFIED>(l, ct, st, d, c0[k], c1[k], c2[k], p[k]);
    }
    *c = [n0, n1, n2, np];
}

/// One DH step on eight poses in structure-of-arrays form (the batch path):
/// [`dh_row`] on each row of each lane.
#[inline(always)]
fn step_soa<const FMA: bool, const MODIFIED: bool>(
    r: &mut [[[f64; LANES]; 3]; 3],
    p: &mut [[f64; LANES]; 3],
    l: &Link,
    ct: &[f64; LANES],
    st: &[f64; LANES],
    d: &[f64; LANES],
) {
    for row in 0..3 {
        for k in 0..LANES {
            let [x0, x1, x2, pk] = dh_row::<FMA, MODIFIED>(
                l,
                ct[k],
                st[k],
                d[k],
                r[row][0][k],
                r[row][1][k],
                r[row][2][k],
                p[row][k],
            );
            r[row][0][k] = x0;
            r[row][1][k] = x1;
            r[row][2][k] = x2;
            p[row][k] = pk;
        }
    }
}
