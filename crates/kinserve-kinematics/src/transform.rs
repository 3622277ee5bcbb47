//! Rigid transforms (rotation + translation) and their conversions: 4×4 matrix,
//! unit quaternion and roll-pitch-yaw.
#![allow(
    clippy::needless_range_loop,
    reason = "matrix code reads best with explicit row/column indices"
)]

use std::ops::Mul;

/// A rigid transform: `p' = rotation · p + translation`.
///
/// `rotation` is row-major (`rotation[row][col]`); `translation` is in whatever
/// length unit the caller works in (kinserve keeps a robot's own unit, m or mm).
///
/// `repr(C)`: twelve doubles, the rotation rows then the translation (the fast
/// paths store poses with whole-vector writes in that layout).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Transform {
    /// Rotation matrix, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation vector (length unit of the model).
    pub translation: [f64; 3],
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// The identity transform.
    pub const IDENTITY: Transform = Transform {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0, 0.0, 0.0],
    };

    /// Builds a transform from a homogeneous 4×4 row-major matrix, taking the
    /// upper 3×4 block as is. Rigidity is not checked here (see [`Transform::rigidity_error`]).
    pub fn from_matrix(m: &[[f64; 4]; 4]) -> Transform {
        let mut t = Transform::IDENTITY;
        for (r, row) in m.iter().take(3).enumerate() {
            t.rotation[r] = [row[0], row[1], row[2]];
            t.translation[r] = row[3];
        }
        t
    }

    /// The homogeneous 4×4 matrix, row-major, last row `[0, 0, 0, 1]`.
    pub fn matrix(&self) -> [[f64; 4]; 4] {
        let r = &self.rotation;
        let p = &self.translation;
        [
            [r[0][0], r[0][1], r[0][2], p[0]],
            [r[1][0], r[1][1], r[1][2], p[1]],
            [r[2][0], r[2][1], r[2][2], p[2]],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// The top three rows of [`Transform::matrix`], row-major:
    /// `[r11, r12, r13, x, r21, r22, r23, y, r31, r32, r33, z]` (the
    /// `matrix` pose format's 12 numbers).
    ///
    /// ```
    /// let t = kinserve_kinematics::Transform::translation(1.0, 2.0, 3.0);
    /// assert_eq!(t.matrix12(), [1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1.0, 3.0]);
    /// ```
    pub fn matrix12(&self) -> [f64; 12] {
        let [r0, r1, r2] = &self.rotation;
        let p = &self.translation;
        [
            r0[0], r0[1], r0[2], p[0], r1[0], r1[1], r1[2], p[1], r2[0], r2[1], r2[2], p[2],
        ]
    }

    /// The translation part (same unit as the transform).
    pub fn position(&self) -> [f64; 3] {
        self.translation
    }

    /// Pure translation.
    pub fn translation(x: f64, y: f64, z: f64) -> Transform {
        Transform {
            translation: [x, y, z],
            ..Transform::IDENTITY
        }
    }

    /// Rotation about x by `angle` rad.
    pub fn rot_x(angle: f64) -> Transform {
        let (s, c) = angle.sin_cos();
        Transform {
            rotation: [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
            translation: [0.0; 3],
        }
    }

    /// Rotation about y by `angle` rad.
    pub fn rot_y(angle: f64) -> Transform {
        let (s, c) = angle.sin_cos();
        Transform {
            rotation: [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
            translation: [0.0; 3],
        }
    }

    /// Rotation about z by `angle` rad.
    pub fn rot_z(angle: f64) -> Transform {
        let (s, c) = angle.sin_cos();
        Transform {
            rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
        }
    }

    /// Translation `[x,y,z]` followed by the rotation `Rz(yaw)·Ry(pitch)·Rx(roll)` (angles in rad).
    pub fn from_translation_rpy(t: [f64; 3], rpy: [f64; 3]) -> Transform {
        let r = Transform::rot_z(rpy[2]) * Transform::rot_y(rpy[1]) * Transform::rot_x(rpy[0]);
        Transform {
            rotation: r.rotation,
            translation: t,
        }
    }

    /// Translation `[x,y,z]` and rotation from a quaternion `[w,x,y,z]`, normalised here.
    /// Returns `None` for a zero or non-finite quaternion. Any other magnitude is
    /// fine: the components are scaled by the largest one before normalising, so
    /// neither `1e200` nor `1e-200` overflows or underflows.
    pub fn from_translation_quaternion(t: [f64; 3], q: [f64; 4]) -> Option<Transform> {
        let big = q.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        if !big.is_finite() || q.iter().any(|c| c.is_nan()) || big == 0.0 {
            return None;
        }
        let q = q.map(|c| c / big);
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        let (w, x, y, z) = (q[0] / n, q[1] / n, q[2] / n, q[3] / n);
        Some(Transform {
            rotation: [
                [
                    1.0 - 2.0 * (y * y + z * z),
                    2.0 * (x * y - w * z),
                    2.0 * (x * z + w * y),
                ],
                [
                    2.0 * (x * y + w * z),
                    1.0 - 2.0 * (x * x + z * z),
                    2.0 * (y * z - w * x),
                ],
                [
                    2.0 * (x * z - w * y),
                    2.0 * (y * z + w * x),
                    1.0 - 2.0 * (x * x + y * y),
                ],
            ],
            translation: t,
        })
    }

    /// Unit quaternion `[w, x, y, z]` of the rotation, with `w ≥ 0`
    /// (Shepperd's method, numerically stable for every rotation).
    pub fn quaternion(&self) -> [f64; 4] {
        let m = &self.rotation;
        let tr = m[0][0] + m[1][1] + m[2][2];
        let q = if tr > 0.0 {
            let s = (tr + 1.0).sqrt() * 2.0;
            [
                0.25 * s,
                (m[2][1] - m[1][2]) / s,
                (m[0][2] - m[2][0]) / s,
                (m[1][0] - m[0][1]) / s,
            ]
        } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
            let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
            [
                (m[2][1] - m[1][2]) / s,
                0.25 * s,
                (m[0][1] + m[1][0]) / s,
                (m[0][2] + m[2][0]) / s,
            ]
        } else if m[1][1] > m[2][2] {
            let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
            [
                (m[0][2] - m[2][0]) / s,
                (m[0][1] + m[1][0]) / s,
                0.25 * s,
                (m[1][2] + m[2][1]) / s,
            ]
        } else {
            let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
            [
                (m[1][0] - m[0][1]) / s,
                (m[0][2] + m[2][0]) / s,
                (m[1][2] + m[2][1]) / s,
                0.25 * s,
            ]
        };
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
        [
            sign * q[0] / n,
            sign * q[1] / n,
            sign * q[2] / n,
            sign * q[3] / n,
        ]
    }

    /// Roll-pitch-yaw `[roll, pitch, yaw]` in rad with `R = Rz(yaw)·Ry(pitch)·Rx(roll)`,
    /// pitch in `[-π/2, π/2]`, roll and yaw in `(-π, π]` (a rounding-level −π is
    /// reported as +π, so the sign of a 1e-17 residue cannot flip the answer).
    /// At gimbal lock (|pitch| = π/2) roll is reported as 0 and the whole rotation
    /// about z goes into yaw.
    pub fn rpy(&self) -> [f64; 3] {
        fn half_open(a: f64) -> f64 {
            if a <= -std::f64::consts::PI {
                std::f64::consts::PI
            } else {
                a
            }
        }
        let m = &self.rotation;
        let cp = (m[0][0] * m[0][0] + m[1][0] * m[1][0]).sqrt();
        let pitch = (-m[2][0]).atan2(cp);
        if cp > 1e-10 {
            [
                half_open(m[2][1].atan2(m[2][2])),
                pitch,
                half_open(m[1][0].atan2(m[0][0])),
            ]
        } else {
            [0.0, pitch, half_open((-m[0][1]).atan2(m[1][1]))]
        }
    }

    /// The inverse transform: rotation `Rᵀ`, translation `−Rᵀ·p`.
    pub fn inverse(&self) -> Transform {
        let r = &self.rotation;
        let p = &self.translation;
        let mut out = Transform::IDENTITY;
        for i in 0..3 {
            for j in 0..3 {
                out.rotation[i][j] = r[j][i];
            }
            out.translation[i] = -(r[0][i] * p[0] + r[1][i] * p[1] + r[2][i] * p[2]);
        }
        out
    }

    /// How far the transform is from rigid: the largest absolute entry of
    /// `RᵀR − I` together with `|det R − 1|`. Rigid transforms give ~1e-16.
    pub fn rigidity_error(&self) -> f64 {
        let r = &self.rotation;
        let mut worst: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                let dot = r[0][i] * r[0][j] + r[1][i] * r[1][j] + r[2][i] * r[2][j];
                let expect = if i == j { 1.0 } else { 0.0 };
                worst = worst.max((dot - expect).abs());
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if worst.is_nan() || det.is_nan() {
            return f64::INFINITY;
        }
        worst.max((det - 1.0).abs())
    }

    /// Largest absolute difference between corresponding entries of two transforms.
    pub fn max_abs_diff(&self, other: &Transform) -> f64 {
        let mut worst: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                worst = worst.max((self.rotation[i][j] - other.rotation[i][j]).abs());
            }
            worst = worst.max((self.translation[i] - other.translation[i]).abs());
        }
        worst
    }

    /// `self · other`.
    #[inline(always)]
    pub fn compose(&self, other: &Transform) -> Transform {
        let a = &self.rotation;
        let b = &other.rotation;
        let p = &other.translation;
        let mut out = Transform::IDENTITY;
        for i in 0..3 {
            for j in 0..3 {
                out.rotation[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
            }
            out.translation[i] =
                a[i][0] * p[0] + a[i][1] * p[1] + a[i][2] * p[2] + self.translation[i];
        }
        out
    }
}

impl Mul for Transform {
    type Output = Transform;
    fn mul(self, rhs: Transform) -> Transform {
        self.compose(&rhs)
    }
}

impl Mul<&Transform> for &Transform {
    type Output = Transform;
    fn mul(self, rhs: &Transform) -> Transform {
        self.compose(rhs)
    }
}
