//! The `kinserve` command line: `serve` (default), `validate`, `fk`, `bench`
//! (in [`crate::bench`]), `healthcheck`.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::path::Path;
use std::process::ExitCode;
use std::time::Duration;

use crate::api::pose::{FkOutput, Pose};
use crate::config::{Cli, Command, FkArgs, ServeConfig};
use crate::error::Error;
use crate::model::{AngleUnit, FkOptions, load_robot_file};

/// Runs the command line and returns the process exit code.
pub fn run(cli: Cli) -> ExitCode {
    match cli.command {
        None => serve(ServeConfig::default()),
        Some(Command::Serve(c)) => serve(*c),
        Some(Command::Validate { files }) => validate(&files),
        Some(Command::Fk(args)) => fk(&args),
        Some(Command::Bench(args)) => crate::bench::run(&args),
        Some(Command::Healthcheck { addr, timeout }) => healthcheck(&addr, timeout),
    }
}

fn serve(config: ServeConfig) -> ExitCode {
    crate::telemetry::init_tracing(config.log_format);
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("kinserve: cannot start the runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    let result = runtime.block_on(async {
        let app = crate::startup::App::build(config).await?;
        app.run_until_stopped().await
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!(error = %e, "kinserve failed");
            eprintln!("kinserve: {e}");
            ExitCode::FAILURE
        }
    }
}

fn print_error(label: &str, e: &Error) {
    let violations = e.violations();
    if violations.is_empty() {
        eprintln!("{label}: {e}");
    } else {
        for v in violations {
            eprintln!("{label}: {v}");
        }
    }
}

fn validate(files: &[std::path::PathBuf]) -> ExitCode {
    let mut failed = 0;
    for f in files {
        match load_robot_file(f) {
            Ok(robot) => println!(
                "{}: ok ({}, {} joints)",
                f.display(),
                robot.name(),
                robot.dof()
            ),
            Err(e) => {
                failed += 1;
                print_error(&f.display().to_string(), &e.into());
            }
        }
    }
    if failed > 0 {
        eprintln!("{failed} of {} file(s) invalid", files.len());
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

fn fk(args: &FkArgs) -> ExitCode {
    let path = match (&args.robot, &args.model) {
        (Some(name), _) => {
            if let Err(m) = crate::model::validate_name(name) {
                eprintln!("--robot: {m}");
                return ExitCode::FAILURE;
            }
            args.robots_dir.join(format!("{name}.json"))
        }
        (None, Some(p)) => p.clone(),
        (None, None) => {
            eprintln!("give --robot NAME or --model FILE");
            return ExitCode::FAILURE;
        }
    };
    let label = path.display().to_string();
    if args.robot.is_some() && !Path::new(&path).exists() {
        eprintln!(
            "no robot '{}' in {}",
            args.robot.as_deref().unwrap_or(""),
            args.robots_dir.display()
        );
        return ExitCode::FAILURE;
    }
    let robot = match load_robot_file(&path) {
        Ok(r) => r,
        Err(e) => {
            print_error(&label, &e.into());
            return ExitCode::FAILURE;
        }
    };
    let unit = if args.deg {
        AngleUnit::Deg
    } else {
        AngleUnit::Rad
    };
    let opts = FkOptions::new(Some(unit), Some(!args.no_limits));
    let result = robot.check_joints(&args.joints, &opts).map(|q| {
        let (t, frames) = q.fk_with_frames(args.frames);
        (t, frames.map(|f| f.iter().map(Pose::from).collect()))
    });
    match result {
        Ok((t, frames)) => {
            let out = FkOutput {
                robot: robot.name().to_string(),
                length_unit: robot.length_unit(),
                pose: Pose::from(&t),
                frames,
            };
            match serde_json::to_string_pretty(&out) {
                Ok(s) => {
                    println!("{s}");
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("cannot print the result: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Err(e) => {
            print_error("--joints", &e.into());
            ExitCode::FAILURE
        }
    }
}

/// `GET /readyz` over a plain TCP connection (no HTTP client needed in the image).
fn healthcheck(addr: &str, timeout: Duration) -> ExitCode {
    let probe = || -> std::io::Result<bool> {
        let sock = addr
            .to_socket_addrs()?
            .next()
            .ok_or_else(|| std::io::Error::other("address resolves to nothing"))?;
        let mut s = TcpStream::connect_timeout(&sock, timeout)?;
        s.set_read_timeout(Some(timeout))?;
        s.set_write_timeout(Some(timeout))?;
        s.write_all(
            format!("GET /readyz HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").as_bytes(),
        )?;
        let mut buf = [0u8; 64];
        let n = s.read(&mut buf)?;
        let head = String::from_utf8_lossy(&buf[..n]);
        Ok(head.starts_with("HTTP/1.1 200") || head.starts_with("HTTP/1.0 200"))
    };
    match probe() {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => {
            eprintln!("kinserve at {addr} is not ready");
            ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("kinserve at {addr} is unreachable: {e}");
            ExitCode::FAILURE
        }
    }
}
