//! Contract tests: the real server on port 0, spoken to with real clients.
mod browser;
mod closed_form;
mod contract;
mod crash;
mod errors;
mod grpc;
mod helpers;
mod hostile;
mod ik;
mod logs;
mod metrics;
mod openapi;
mod pagination;
mod rest;
mod secure_defaults;
mod ws;
