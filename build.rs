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
        // Compiled only into the descriptor set (served by reflection) so
        // that tools such as grpcurl decode the BadRequest details we send.
        "proto/google/rpc/error_details.proto",
    ];
    for p in protos {
        println!("cargo:rerun-if-changed={p}");
    }
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    embed_builtin_robots(&out)?;
    tonic_prost_build::configure()
        .file_descriptor_set_path(out.join("kinematics_descriptor.bin"))
        .extern_path(".google.rpc", "::tonic_types")
        // Rarely set, large submessages of the stream messages are boxed, so
        // that every FK reply moved through the stream's queue is small
        // (696 → ~200 bytes; the moves were ~15 % of a stream's server time).
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.jacobian")
        .boxed(".kinematics.v1.StreamForwardKinematicsResponse.ik")
        .boxed(".kinematics.v1.StreamForwardKinematicsRequest.ik")
        .compile_protos(
            &[
                std::path::PathBuf::from(protos[0]),
                std::path::PathBuf::from(protos[2]),
            ],
            &[
                std::path::PathBuf::from("proto"),
                protoc_bin_vendored::include_path()?,
            ],
        )?;
    Ok(())
}

/// Writes `builtin_robots.rs`: every `robots/*.json` as `(file name, bytes)`,
/// sorted by name, so the binary carries its built-in robots and works from
/// any directory (`src/registry/builtin.rs` reads the list).
fn embed_builtin_robots(out: &std::path::Path) -> Result<(), Box<dyn std::error::Error>> {
    println!("cargo:rerun-if-changed=robots");
    let dir = std::path::Path::new(&std::env::var("CARGO_MANIFEST_DIR")?).join("robots");
    let mut files: Vec<_> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    let mut code = String::from(
        "/// Built-in robot files: (file name, contents).\npub(crate) static EMBEDDED: &[(&str, &[u8])] = &[\n",
    );
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
        let name = f
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or("robot file name is not UTF-8")?;
        code.push_str(&format!(
            "    ({name:?}, include_bytes!({:?})),\n",
            f.display().to_string()
        ));
    }
    code.push_str("];\n");
    std::fs::write(out.join("builtin_robots.rs"), code)?;
    Ok(())
}
