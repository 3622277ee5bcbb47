//! Generates the gRPC code from proto/ with a vendored protoc (no system protoc needed).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    if std::env::var_os("PROTOC").is_none() {
        let protoc = protoc_bin_vendored::protoc_bin_path()?;
        // SAFETY: build scripts are single-threaded at this point.
        unsafe { std::env::set_var("PROTOC", protoc) };
    }
    let protos = [
        "proto/kinematics/v1/kinematics.proto",
        "proto/google/rpc/status.proto",
    ];
    for p in protos {
        println!("cargo:rerun-if-changed={p}");
    }
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    tonic_prost_build::configure()
        .file_descriptor_set_path(out.join("kinematics_descriptor.bin"))
        .extern_path(".google.rpc.Status", "::tonic_types::Status")
        .compile_protos(
            &[std::path::PathBuf::from(protos[0])],
            &[
                std::path::PathBuf::from("proto"),
                protoc_bin_vendored::include_path()?,
            ],
        )?;
    Ok(())
}
