//! The model crate's tests, one binary: validation of every robot file and
//! the documented field errors of bad models (`model`), validated IK and
//! Jacobian requests (`ik_requests`), the symbolic closed forms against FK and
//! the course notes (`closed_form`) and the URDF export read back and
//! evaluated (`urdf`).
//!
//! Needs only the math crates (`kinserve-testkit` without its `server`
//! feature for the unchecked FK of expected values).
mod closed_form;
mod ik_path;
mod ik_requests;
mod ik_solutions;
mod model;
mod urdf;
mod urdf_import;
