//! Conversions to and from nalgebra (feature `nalgebra`), for callers who do
//! their own linear algebra on poses. Owns nothing else.

use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion};

use crate::Transform;

impl From<&Transform> for Matrix4<f64> {
    fn from(t: &Transform) -> Self {
        let m = t.matrix();
        Matrix4::from_fn(|i, j| m[i][j])
    }
}

impl From<&Transform> for Isometry3<f64> {
    fn from(t: &Transform) -> Self {
        let r = &t.rotation;
        let rot = Rotation3::from_matrix_unchecked(Matrix3::from_fn(|i, j| r[i][j]));
        let [x, y, z] = t.translation;
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_rotation_matrix(&rot),
        )
    }
}

impl From<&Isometry3<f64>> for Transform {
    fn from(iso: &Isometry3<f64>) -> Self {
        let m = iso.to_homogeneous();
        let mut a = [[0.0; 4]; 4];
        for (i, row) in a.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = m[(i, j)];
            }
        }
        Transform::from_matrix(&a)
    }
}
