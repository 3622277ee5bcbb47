//! Generates the gRPC code from the workspace's `proto/` with a vendored
//! protoc (no system protoc needed).

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    if std::env::var_os("PROTOC").is_none() {
        let protoc = protoc_bin_vendored::protoc_bin_path()?;
        // SAFETY: build scripts are single-threaded at this point.
        unsafe { std::env::set_var("PROTOC", protoc) };
    }
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?)
        .join("../../proto")
        .canonicalize()?;
    let protos = [
        root.join("kinematics/v1/kinematics.proto"),
        root.join("google/rpc/status.proto"),
        // Compiled only into the descriptor set (served by reflection) so
        // that tools such as grpcurl decode the BadRequest details we send.
        root.join("google/rpc/error_details.proto"),
        // Imported publicly by kinematics.proto (compiled through it).
        root.join("kinematics/v1/types.proto"),
    ];
    for p in &protos {
        println!("cargo:rerun-if-changed={}", p.display());
    }
    let out = PathBuf::from(std::env::var("OUT_DIR")?);
    tonic_prost_build::configure()
        .file_descriptor_set_path(out.join("kinematics_descriptor.bin"))
        .extern_path(".google.rpc", "::tonic_types")
        .codec_path("crate::codec::ReservingCodec")
        // The messages of a batch's numbers, hand-written to read and write
        // their packed doubles in bulk (see `src/wire.rs`).
        .extern_path(
            ".kinematics.v1.JointConfiguration",
            "crate::wire::JointConfiguration",
        )
        .extern_path(".kinematics.v1.PackedPoses", "crate::wire::PackedPoses")
        .extern_path(
            ".kinematics.v1.PackedConfigurations",
            "crate::wire::PackedConfigurations",
        )
        // Rarely set, large submessages of the stream messages are boxed, so
        // that every FK reply moved through the stream's queue is small
        // (696 → ~200 bytes; the moves were ~15 % of a stream's server time).
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.jacobian")
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.ik")
        .boxed(".kinematics.v1.StreamForwardKinematicsRequest.ik")
        // The paths too (336 and 112 bytes inline): with them every FK
        // message and reply was 448 bytes, moved several times per message.
        .boxed(".kinematics.v1.StreamForwardKinematicsRequest.ik_path")
        .boxed(".kinematics.v1.StreamForwardKinematicsRequest.packed_configurations")
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.ik_path")
        // The full pose (168 bytes) in the reply's oneof, and the packed
        // frames and poses (32 each) the other messages carry: inline, they
        // made every compact FK reply 344 bytes, moved about a dozen times.
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.result.pose")
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.packed_frames")
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.packed_poses")
        .compile_protos(
            &[protos[0].clone(), protos[2].clone()],
            &[root, protoc_bin_vendored::include_path()?],
        )?;
    Ok(())
}
