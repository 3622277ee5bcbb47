//! The kinematics crate's tests, one binary: the fast FK paths against the
//! plain product of link matrices and the vectorised sine/cosine against
//! `std` (`kinematics`), property tests over random tables (`properties`),
//! the Jacobian against differences of FK (`jacobian`), numerical IK round
//! trips (`ik`) and their posture and per-axis objectives (`ik_objectives`), and FK of the robot files in `robots/` against the course
//! notes' closed forms (`closed_forms`) and against published poses
//! (`published_poses`).
//!
//! Needs only the math crates: robot files are read with `kinserve-model`
//! and the reference product comes from `kinserve-testkit` (without its
//! `server` feature), both dev-dependencies.
mod analytic_ik;
mod closed_forms;
mod ik;
mod ik_objectives;
mod jacobian;
mod kinematics;
mod properties;
mod published_poses;
