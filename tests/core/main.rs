//! Core tests: kinematics, model validation, robot files, CLI.
mod closed_forms;
mod kinematics;
mod published_poses;
