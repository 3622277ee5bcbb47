//! Core tests: kinematics, model validation, robot files, CLI.
mod kinematics;
