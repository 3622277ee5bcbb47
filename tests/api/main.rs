//! Contract tests: the real server on port 0, spoken to with real clients.
mod browser;
mod contract;
mod crash;
mod grpc;
mod helpers;
mod hostile;
mod ik;
mod rest;
mod ws;
