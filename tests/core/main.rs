//! Core tests: kinematics, model validation, robot files, CLI.
mod builtins;
mod cli;
mod closed_forms;
mod fuzz_corpus;
mod helpers;
mod ik;
mod ik_requests;
mod jacobian;
mod kinematics;
mod model;
mod properties;
mod published_poses;
mod readme;
mod service_limits;
