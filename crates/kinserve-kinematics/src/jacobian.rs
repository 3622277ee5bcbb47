//! The geometric Jacobian of a serial chain, analytic from the frames forward
//! kinematics already computes, and (feature `nalgebra`) the measures derived
//! from its singular values: manipulability, condition number, singularity.
//!
//! Owns [`Jacobian`], [`JacobianFrame`], [`Chain::jacobian`] /
//! [`Chain::jacobian_into`] and [`VelocityMeasures`]. Uses only the public
//! [`Chain`] API (`forward_frames_into`, `dh_rows`, `convention`); must not
//! depend on serde or on any other kinserve crate.
//!
//! Units: rows 0–2 (linear velocity `v` of the tool point) are in the chain's
//! length unit per rad (revolute column) or per length unit (prismatic column,
//! i.e. dimensionless); rows 3–5 (angular velocity `ω`) are 1/rad per rad
//! (revolute, dimensionless) or per length unit (prismatic, always 0). Columns
//! are per radian whatever `angle_scale` the joint values were given with.

use crate::chain::Chain;
use crate::dh::{Convention, JointKind};
use crate::transform::Transform;

/// The frame a Jacobian's rows are expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum JacobianFrame {
    /// The world frame FK poses are given in (the base transform included):
    /// `[v; ω]` of the tool point in world coordinates (`jacob0`).
    #[default]
    Base,
    /// The tool frame: the same twist rotated into the tool's own axes,
    /// `[Rᵀ v; Rᵀ ω]` with `R` the tool orientation (`jacobe`).
    Tool,
}

/// A geometric Jacobian: 6 rows `(vx, vy, vz, ωx, ωy, ωz)` × one column per
/// movable joint, stored column by column.
#[derive(Clone, Debug, PartialEq)]
pub struct Jacobian {
    columns: Vec<[f64; 6]>,
}

impl Jacobian {
    /// A Jacobian from its columns (`[vx, vy, vz, ωx, ωy, ωz]` per joint).
    pub fn from_columns(columns: Vec<[f64; 6]>) -> Jacobian {
        Jacobian { columns }
    }

    /// Number of columns (movable joints).
    pub fn dof(&self) -> usize {
        self.columns.len()
    }

    /// The columns, one per movable joint in table order.
    pub fn columns(&self) -> &[[f64; 6]] {
        &self.columns
    }

    /// Entry at `row` (0–5) and `col` (joint index); `None` out of range.
    pub fn get(&self, row: usize, col: usize) -> Option<f64> {
        self.columns.get(col).and_then(|c| c.get(row)).copied()
    }

    /// The six rows, each with one value per joint (row-major, as JSON carries it).
    pub fn rows(&self) -> [Vec<f64>; 6] {
        std::array::from_fn(|r| self.columns.iter().map(|c| c[r]).collect())
    }
}

/// `a × b`.
#[inline(always)]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `Rᵀ v` for a row-major rotation.
#[inline(always)]
fn rotate_back(r: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| r[0][i] * v[0] + r[1][i] * v[1] + r[2][i] * v[2])
}

impl Chain {
    /// The geometric Jacobian at `q` (revolute values times `angle_scale`)
    /// for the tool point, in `frame`, and the tool pose. Allocates the columns.
    ///
    /// Unchecked like [`Chain::forward`]: the caller guarantees `q.len() == dof`
    /// and finite values.
    pub fn jacobian(
        &self,
        q: &[f64],
        angle_scale: f64,
        frame: JacobianFrame,
    ) -> (Transform, Jacobian) {
        let mut columns = vec![[0.0; 6]; self.dof()];
        let tool = self.jacobian_into(q, angle_scale, frame, &mut columns);
        (tool, Jacobian { columns })
    }

    /// [`Chain::jacobian`] into `columns` (one per movable joint; extra entries
    /// are left alone, missing ones skipped). Returns the tool pose. Allocates
    /// nothing: one pass of [`Chain::forward_frames_into`] plus a cross product
    /// per revolute joint.
    ///
    /// Joint `k`'s axis is `z` of the frame before its row in standard DH
    /// (`z_{k-1}`) and of the frame after it in modified DH (`z_k`); the
    /// frame's origin lies on that axis in both. A revolute column is
    /// `[z × (p_tool − o); z]`, a prismatic one `[z; 0]`.
    pub fn jacobian_into(
        &self,
        q: &[f64],
        angle_scale: f64,
        frame: JacobianFrame,
        columns: &mut [[f64; 6]],
    ) -> Transform {
        let modified = self.convention() == Convention::Modified;
        let mut rows = self.dh_rows();
        // Joint j's frame, as (origin, z axis), is stored in its column first.
        // Frame i (0 = base) holds the axis of row i in standard DH and of row
        // i-1 in modified DH.
        let mut pending = false;
        let mut j = 0;
        let mut record = |t: &Transform| {
            if let Some(c) = columns.get_mut(j) {
                let (r, p) = (&t.rotation, t.translation);
                *c = [p[0], p[1], p[2], r[0][2], r[1][2], r[2][2]];
            }
            j += 1;
        };
        let tool = self.forward_frames_into(q, angle_scale, &mut |t| {
            let movable = rows.next().is_some_and(|r| r.kind != JointKind::Fixed);
            if modified {
                if pending {
                    record(t);
                }
                pending = movable;
            } else if movable {
                record(t);
            }
        });
        let pe = tool.translation;
        for (c, kind) in columns.iter_mut().zip(self.joint_kinds()) {
            let z = [c[3], c[4], c[5]];
            *c = match kind {
                JointKind::Revolute => {
                    let v = cross(z, [pe[0] - c[0], pe[1] - c[1], pe[2] - c[2]]);
                    [v[0], v[1], v[2], z[0], z[1], z[2]]
                }
                _ => [z[0], z[1], z[2], 0.0, 0.0, 0.0],
            };
            if frame == JacobianFrame::Tool {
                let v = rotate_back(&tool.rotation, [c[0], c[1], c[2]]);
                let w = rotate_back(&tool.rotation, [c[3], c[4], c[5]]);
                *c = [v[0], v[1], v[2], w[0], w[1], w[2]];
            }
        }
        tool
    }
}

/// Below this smallest singular value a Jacobian counts as singular: 1e-6 in
/// the Jacobian's own units (length unit per rad for the linear rows, 1 for the
/// angular ones). An absolute bound, so for millimetre models the linear rows
/// weigh 1000× more than for metre models; the condition number is the
/// unit-free companion.
#[cfg(feature = "nalgebra")]
pub const SINGULAR_THRESHOLD: f64 = 1e-6;

/// What the singular values `σ_1 ≥ … ≥ σ_m` of a Jacobian say, over the rows
/// that matter for the arm: the three linear rows for arms of up to 3 joints
/// (they place the tool point and cannot also set its orientation), all six
/// rows otherwise; `m = min(rows, dof)`.
#[cfg(feature = "nalgebra")]
#[derive(Clone, Debug, PartialEq)]
pub struct VelocityMeasures {
    /// Yoshikawa's manipulability `√det(J Jᵀ)` over all six rows for
    /// `dof ≥ 6`; `√det(Jᵀ J)` over all six rows for 4 or 5 joints (where
    /// `det(J Jᵀ)` is 0); over the linear rows `J_v` for up to 3 joints,
    /// `√det(J_v J_vᵀ)` for 3 and `√det(J_vᵀ J_v)` for 1 or 2. Each is the
    /// product `σ_1 ⋯ σ_m`.
    pub manipulability: f64,
    /// `σ_1 / σ_m`; infinite when `σ_m` is exactly 0.
    pub condition_number: f64,
    /// `σ_m <` [`SINGULAR_THRESHOLD`].
    pub singular: bool,
    /// The singular values, largest first.
    pub singular_values: Vec<f64>,
    /// How many rows the measures use: 3 (linear rows, up to 3 joints) or 6.
    pub rows: usize,
}

#[cfg(feature = "nalgebra")]
impl Jacobian {
    /// Rows the measures use for this many joints (see [`VelocityMeasures`]).
    pub fn measure_rows(dof: usize) -> usize {
        if dof <= 3 { 3 } else { 6 }
    }

    /// Manipulability, condition number and singularity from the singular
    /// values (nalgebra's SVD) of the rows that matter (see
    /// [`VelocityMeasures`]). A Jacobian whose SVD does not converge (not
    /// seen for finite input) is reported singular with NaN measures.
    pub fn measures(&self) -> VelocityMeasures {
        let n = self.columns.len();
        let rows = Self::measure_rows(n);
        let m = nalgebra::DMatrix::from_fn(rows, n, |r, c| self.columns[c][r]);
        let sv: Vec<f64> = match nalgebra::SVD::try_new(m, false, false, f64::EPSILON, 10_000) {
            Some(svd) => {
                let mut s: Vec<f64> = svd.singular_values.iter().copied().collect();
                s.sort_by(|a, b| b.total_cmp(a));
                s
            }
            None => vec![f64::NAN; n.min(rows)],
        };
        let largest = sv.first().copied().unwrap_or(0.0);
        let smallest = sv.last().copied().unwrap_or(0.0);
        let condition_number = if smallest == 0.0 {
            f64::INFINITY
        } else {
            largest / smallest
        };
        VelocityMeasures {
            manipulability: sv.iter().product(),
            condition_number,
            // NaN (an SVD that did not converge) counts as singular.
            singular: smallest.is_nan() || smallest < SINGULAR_THRESHOLD,
            singular_values: sv,
            rows,
        }
    }
}
