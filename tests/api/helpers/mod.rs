//! Shared helpers for the API tests, by kind, all re-exported here so that
//! `use crate::helpers::*;` gives every one of them.
//!
//! Two functions are called `assert_pose_eq`: [`pose::assert_pose_eq`] for
//! JSON poses and [`grpc::assert_pose_eq`] for protobuf poses; a test file
//! that uses one imports it by path.

pub(crate) mod app;
pub(crate) mod browser;
pub(crate) mod checker;
pub(crate) mod corpus;
pub(crate) mod cross_protocol;
pub(crate) mod doc_blocks;
pub(crate) mod grpc;
pub(crate) mod h2grpc;
pub(crate) mod http;
pub(crate) mod models;
pub(crate) mod pose;
pub(crate) mod pose_format;
pub(crate) mod postgres;
pub(crate) mod process;
pub(crate) mod raw;
pub(crate) mod readme;
pub(crate) mod tls;
pub(crate) mod witness;
pub(crate) mod ws;

pub(crate) use app::*;
pub(crate) use checker::*;
pub(crate) use corpus::*;
pub(crate) use cross_protocol::*;
pub(crate) use grpc::*;
pub(crate) use h2grpc::*;
pub(crate) use http::*;
pub(crate) use models::*;
pub(crate) use pose::*;
pub(crate) use pose_format::*;
pub(crate) use postgres::*;
pub(crate) use process::*;
pub(crate) use raw::*;
pub(crate) use readme::*;
pub(crate) use witness::*;
pub(crate) use ws::*;
