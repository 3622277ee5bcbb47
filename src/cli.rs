//! The `kinserve` command line: `serve` (default), `validate`, `fk`,
//! `jacobian`, `ik`, `ik-path`, `closed-form`, `urdf`, `import-urdf`, `bench` (in [`crate::bench`]),
//! `healthcheck`.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::process::ExitCode;
use std::time::Duration;

use crate::api::ik::{IkItem, IkOutput, IkPathOutput};
use crate::api::jacobian::{JacobianItem, JacobianOutput};
use crate::api::pose::{FkOutput, Pose};
use crate::api::rest::ops::RestOp;
use crate::config::{
    Cli, ClosedFormArgs, ClosedFormFormat, Command, ConfigArgs, ConventionArg, FkArgs, FrameArg,
    IkArgs, IkPathArgs, ImportUrdfArgs, JacobianArgs, ModelArgs, OpCommand, ServeConfig, SolverArg,
};
use crate::error::Error;
use crate::model::operations;
use crate::model::{
    AngleUnit, ClosedForm, ConventionSpec, FkOptions, IkPathSpec, IkSolutionsMode, IkSolverChoice,
    IkSpec, IkTargetSpec, ModelLimits, QuaternionSpec, ReferenceFrame, Robot, UrdfImport,
    import_urdf, load_robot_file, to_urdf,
};
use crate::registry::builtin;

/// Writes the result to stdout. A closed pipe (`kinserve … | head`) is a
/// normal end: the process exits 0 at once instead of panicking.
fn write_out(args: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("kinserve: cannot write the result: {e}");
        std::process::exit(1);
    }
}

/// `print!` to stdout through [`write_out`].
macro_rules! out {
    ($($t:tt)*) => { write_out(format_args!($($t)*)) };
}

/// `println!` to stdout through [`write_out`].
macro_rules! outln {
    ($($t:tt)*) => { write_out(format_args!("{}\n", format_args!($($t)*))) };
}

/// Runs the command line and returns the process exit code.
pub fn run(cli: Cli) -> ExitCode {
    match cli.command {
        None => serve(ServeConfig::default()),
        Some(Command::Serve(c)) => serve(*c),
        Some(Command::Validate { files }) => validate(&files),
        Some(Command::Fk(args)) => fk(&args),
        Some(Command::Jacobian(args)) => jacobian(&args),
        Some(Command::Op(op)) => config_op(&op),
        Some(Command::Ik(args)) => ik(&args),
        Some(Command::IkPath(args)) => ik_path(&args),
        Some(Command::ClosedForm(args)) => closed_form(&args),
        Some(Command::Urdf(args)) => urdf(&args),
        Some(Command::ImportUrdf(args)) => import_urdf_file(&args),
        Some(Command::Bench(args)) => match load_model(&args.which) {
            Ok(robot) => crate::bench::run(&robot, &args),
            Err(code) => code,
        },
        Some(Command::Healthcheck {
            addr,
            timeout,
            tls,
            client_cert,
            client_key,
        }) => {
            let client = client_cert.as_deref().zip(client_key.as_deref());
            healthcheck(&addr, timeout, tls.then_some(client))
        }
    }
}

fn serve(config: ServeConfig) -> ExitCode {
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
    let tracing = crate::telemetry::traces::init(
        config.log_format,
        crate::telemetry::traces::LogLines::OffThread,
        &config.traces,
        Some(runtime.handle()),
    );
    let tracing = match tracing {
        Ok(t) => t,
        Err(e) => {
            eprintln!("kinserve: {e}");
            return ExitCode::FAILURE;
        }
    };
    let result = runtime.block_on(async {
        let app = crate::startup::App::build(config).await?;
        app.run_until_stopped().await
    });
    if let Err(e) = &result {
        tracing::error!(error = %e, "kinserve failed");
    }
    // The spans and log lines still buffered go out while the runtime still runs.
    tracing.shutdown();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("kinserve: {e}");
            ExitCode::FAILURE
        }
    }
}

fn print_error(label: &str, e: &Error) {
    let violations = e.violations();
    if violations.is_empty() {
        eprintln!("{label}: {}", on_the_command_line(&e.to_string()));
    } else {
        for v in violations {
            eprintln!("{label}: {}", on_the_command_line(&v.to_string()));
        }
    }
}

/// The API's hints in the command line's words (`--deg`, not `angle_unit "deg"`).
fn on_the_command_line(message: &str) -> String {
    message.replace("send angle_unit \"deg\"", "pass --deg")
}

/// A robot file, or its errors printed (a missing file said plainly, not as malformed input).
fn load_file(path: &std::path::Path) -> Option<crate::model::Robot> {
    let label = path.display().to_string();
    if !path.exists() {
        eprintln!("{label}: no such file");
        return None;
    }
    load_robot_file(path)
        .map_err(|e| print_error(&label, &Error::from(e)))
        .ok()
}

fn validate(files: &[std::path::PathBuf]) -> ExitCode {
    let mut failed = 0;
    for f in files {
        match load_file(f) {
            Some(robot) => outln!(
                "{}: ok ({}, {} joints)",
                f.display(),
                robot.name(),
                robot.dof()
            ),
            None => failed += 1,
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
    let robot = match load_model(&args.which) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let unit = angle_unit(args.deg);
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
                pose: Some(Pose::from(&t)),
                matrix: None,
                position: None,
                frames,
                frame_matrices: None,
                frame_positions: None,
            };
            print_json(&out, ExitCode::SUCCESS)
        }
        Err(e) => {
            print_error("--joints", &e.into());
            ExitCode::FAILURE
        }
    }
}

/// The angle unit of the joint values the flags give (`--deg` or rad).
fn angle_unit(deg: bool) -> AngleUnit {
    if deg { AngleUnit::Deg } else { AngleUnit::Rad }
}

/// Prints `value` as pretty JSON; `code` if that worked.
/// Prints `value` as indented JSON with every list of scalars on one line
/// (so a 4×4 matrix reads as four rows), then returns `code`.
fn print_json(value: &impl serde::Serialize, code: ExitCode) -> ExitCode {
    match serde_json::to_string_pretty(value) {
        Ok(s) => {
            let s = scalar_lists_on_one_line(&s);
            outln!("{s}");
            code
        }
        Err(e) => {
            eprintln!("cannot print the result: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Rewrites serde_json's pretty output so that an array holding only
/// scalars (numbers, strings, booleans, null) is one line, `[1.0, -0.0, 2.5]`;
/// arrays of arrays or objects stay one element per line. The values and
/// their text are unchanged (only whitespace moves).
///
/// ```text
/// "position": [        ->   "position": [0.4521, -0.15005, 1.10363]
///   0.4521,
///   -0.15005,
///   1.10363
/// ]
/// ```
fn scalar_lists_on_one_line(pretty: &str) -> String {
    let lines: Vec<&str> = pretty.lines().collect();
    let mut out: Vec<String> = Vec::with_capacity(lines.len());
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        if line.ends_with('[') {
            let items: Vec<&str> = lines[i + 1..]
                .iter()
                .take_while(|l| !l.trim_start().starts_with(']'))
                .map(|l| l.trim())
                .collect();
            let close = lines.get(i + 1 + items.len()).map(|l| l.trim());
            if let Some(close) = close
                && !items.is_empty()
                && items.iter().all(|item| is_scalar(item))
            {
                let joined = items.join(" ");
                out.push(format!("{line}{joined}{close}"));
                i += items.len() + 2;
                continue;
            }
        }
        out.push(line.to_string());
        i += 1;
    }
    out.join("\n")
}

/// Whether one line of pretty JSON is a scalar array element (with its comma).
fn is_scalar(item: &str) -> bool {
    let value = item.strip_suffix(',').unwrap_or(item);
    serde_json::from_str::<serde_json::Value>(value).is_ok_and(|v| !(v.is_array() || v.is_object()))
}

fn jacobian(args: &JacobianArgs) -> ExitCode {
    let robot = match load_model(&args.which) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let unit = angle_unit(args.deg);
    let frame = match args.frame {
        FrameArg::Base => ReferenceFrame::Base,
        FrameArg::Tool => ReferenceFrame::Tool,
    };
    let opts = FkOptions::new(Some(unit), Some(!args.no_limits));
    match robot.check_joints(&args.joints, &opts) {
        Ok(q) => {
            let out = JacobianOutput {
                robot: robot.name().to_string(),
                length_unit: robot.length_unit(),
                result: JacobianItem::from(&q.jacobian(frame)),
            };
            print_json(&out, ExitCode::SUCCESS)
        }
        Err(e) => {
            print_error("--joints", &e.into());
            ExitCode::FAILURE
        }
    }
}

/// Runs the subcommand of an operation on one configuration.
macro_rules! cli_config_ops {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
        fn config_op(op: &OpCommand) -> ExitCode {
            match op {
                $( OpCommand::$op(args) => config_answer::<operations::$op>(args), )*
            }
        }
    };
}

crate::model::config_ops!(cli_config_ops);

/// Prints `Op`'s REST answer at the flags' configuration.
fn config_answer<Op: RestOp>(args: &ConfigArgs) -> ExitCode {
    let robot = match load_model(&args.which) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let unit = angle_unit(args.deg);
    let opts = FkOptions::new(Some(unit), Some(!args.no_limits));
    match robot.check_joints(&args.joints, &opts) {
        Ok(q) => print_json(&Op::output(&robot, Op::compute(&q)), ExitCode::SUCCESS),
        Err(e) => {
            print_error("--joints", &e.into());
            ExitCode::FAILURE
        }
    }
}

/// The IK request the flags describe (shape errors of the flags printed).
fn ik_spec(args: &IkArgs) -> Option<IkSpec> {
    let matrix = match args.matrix.as_deref() {
        None => None,
        Some(v) => match <[f64; 16]>::try_from(v) {
            Ok(m) => Some(std::array::from_fn(|i| {
                std::array::from_fn(|j| m[i * 4 + j])
            })),
            Err(_) => {
                eprintln!("--matrix: give 16 values (row-major 4x4), got {}", v.len());
                return None;
            }
        },
    };
    let position = match args.position.as_deref() {
        None => None,
        Some(v) => match <[f64; 3]>::try_from(v) {
            Ok(p) => Some(p),
            Err(_) => {
                eprintln!("--position: give x,y,z, got {} values", v.len());
                return None;
            }
        },
    };
    let quaternion = match args.quaternion.as_deref() {
        None => None,
        Some(&[w, x, y, z]) => Some(QuaternionSpec { w, x, y, z }),
        Some(v) => {
            eprintln!("--quaternion: give w,x,y,z, got {} values", v.len());
            return None;
        }
    };
    Some(IkSpec {
        target: IkTargetSpec {
            matrix,
            position,
            quaternion,
        },
        seed: args.seed.clone(),
        angle_unit: angle_unit(args.deg),
        position_only: args.position_only,
        tolerance: args.tolerance,
        max_iterations: args.max_iterations,
        restarts: args.restarts,
        solver: solver(args.solver),
        solutions: if args.all {
            IkSolutionsMode::All
        } else {
            IkSolutionsMode::Best
        },
        max_solutions: args.max_solutions,
        posture: args.objectives.posture(),
        axis_tolerances: args.objectives.axis_tolerances(),
        free_axes: args.objectives.free_axis.clone(),
    })
}

fn ik(args: &IkArgs) -> ExitCode {
    let robot = match load_model(&args.which) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let Some(spec) = ik_spec(args) else {
        return ExitCode::FAILURE;
    };
    let request = match robot.check_ik(&spec) {
        Ok(r) => r,
        Err(e) => {
            print_error("ik", &e.into());
            return ExitCode::FAILURE;
        }
    };
    let answer = request.solve(std::time::Instant::now().checked_add(args.time_limit));
    let out = IkOutput {
        robot: robot.name().to_string(),
        length_unit: robot.length_unit(),
        angle_unit: spec.angle_unit,
        result: IkItem::from(&answer),
    };
    if answer.converged {
        print_json(&out, ExitCode::SUCCESS)
    } else {
        eprintln!(
            "ik: {}",
            Error::ik_not_converged(answer, robot.length_unit().as_str())
        );
        print_json(&out, ExitCode::FAILURE)
    }
}

/// `kinserve ik-path`: the path the flags describe, solved once.
fn ik_path(args: &IkPathArgs) -> ExitCode {
    let robot = match load_model(&args.which) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let mut waypoints = Vec::new();
    for (i, w) in args.waypoints.iter().enumerate() {
        match waypoint(w, args.position_only) {
            Ok(t) => waypoints.push(t),
            Err(e) => {
                eprintln!("--waypoint #{}: {e}", i + 1);
                return ExitCode::FAILURE;
            }
        }
    }
    let spec = IkPathSpec {
        start: args.start.clone(),
        waypoints,
        angle_unit: angle_unit(args.deg),
        position_only: args.position_only,
        max_step_length: args.max_step_length,
        max_step_angle: args.max_step_angle,
        max_joint_step: args.max_joint_step,
        tolerance: args.tolerance,
        solver: solver(args.solver),
        posture: args.objectives.posture(),
        axis_tolerances: args.objectives.axis_tolerances(),
        free_axes: args.objectives.free_axis.clone(),
        ..IkPathSpec::default()
    };
    let request = match robot.check_ik_path(&spec, 10_000) {
        Ok(r) => r,
        Err(e) => {
            print_error("ik-path", &e.into());
            return ExitCode::FAILURE;
        }
    };
    let answer = request.solve(std::time::Instant::now().checked_add(args.time_limit));
    let out = IkPathOutput::new(robot.name(), robot.length_unit(), spec.angle_unit, answer);
    match &out.stop {
        None => print_json(&out, ExitCode::SUCCESS),
        Some(stop) => {
            eprintln!(
                "ik-path: stopped at step {} (waypoint {}): {}: {}",
                stop.step,
                stop.waypoint,
                stop.reason.as_str(),
                stop.detail
            );
            print_json(&out, ExitCode::FAILURE)
        }
    }
}

/// One `--waypoint`: 7 numbers (position, quaternion w,x,y,z) or 3 with
/// `--position-only`.
fn waypoint(text: &str, position_only: bool) -> Result<IkTargetSpec, String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match (v.as_slice(), position_only) {
        (&[x, y, z, w, qx, qy, qz], _) => Ok(IkTargetSpec {
            position: Some([x, y, z]),
            quaternion: Some(QuaternionSpec {
                w,
                x: qx,
                y: qy,
                z: qz,
            }),
            matrix: None,
        }),
        (&[x, y, z], true) => Ok(IkTargetSpec {
            position: Some([x, y, z]),
            ..IkTargetSpec::default()
        }),
        _ => Err(format!(
            "give x,y,z,w,qx,qy,qz (or x,y,z with --position-only), got {} values",
            v.len()
        )),
    }
}

fn solver(s: SolverArg) -> IkSolverChoice {
    match s {
        SolverArg::Auto => IkSolverChoice::Auto,
        SolverArg::Analytic => IkSolverChoice::Analytic,
        SolverArg::Numeric => IkSolverChoice::Numeric,
    }
}

/// The one loader of the commands that work on a robot: a built-in by name
/// (`--robots-dir` adds or overrides) or a model file; errors printed.
fn load_model(args: &ModelArgs) -> Result<Robot, ExitCode> {
    let robots_dir = args.robots_dir.as_deref();
    let (robot, model) = (args.robot.as_deref(), args.model.as_deref());
    let (label, loaded) = match (robot, model) {
        (Some(name), _) => {
            if let Err(m) = crate::model::validate_name(name) {
                eprintln!("--robot: {m}");
                return Err(ExitCode::FAILURE);
            }
            match builtin::find(name, robots_dir, &ModelLimits::default()) {
                Some(found) => found,
                None => {
                    let names: Vec<_> = builtin::embedded_names().collect();
                    eprintln!(
                        "no built-in robot '{name}' (built-in: {}); give --model FILE for your own",
                        names.join(", ")
                    );
                    return Err(ExitCode::FAILURE);
                }
            }
        }
        (None, Some(p)) => match load_file(p) {
            Some(robot) => (p.display().to_string(), Ok(robot)),
            None => return Err(ExitCode::FAILURE),
        },
        (None, None) => {
            eprintln!("give --robot NAME or --model FILE");
            return Err(ExitCode::FAILURE);
        }
    };
    loaded.map_err(|e| {
        print_error(&label, &e);
        ExitCode::FAILURE
    })
}

fn closed_form(args: &ClosedFormArgs) -> ExitCode {
    let robot = match load_model(&args.which) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let cf = match ClosedForm::of(&robot) {
        Ok(cf) => cf,
        Err(e) => {
            print_error(robot.name(), &e.into());
            return ExitCode::FAILURE;
        }
    };
    let out = match args.format {
        ClosedFormFormat::Json => match serde_json::to_string_pretty(&cf) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("cannot print the result: {e}");
                return ExitCode::FAILURE;
            }
        },
        ClosedFormFormat::Text => cf
            .transform
            .text
            .iter()
            .map(|r| r.join(" | "))
            .collect::<Vec<_>>()
            .join("\n"),
        ClosedFormFormat::Latex => cf.transform.latex,
        ClosedFormFormat::Mathml => cf.transform.mathml,
    };
    outln!("{out}");
    ExitCode::SUCCESS
}

fn urdf(args: &ModelArgs) -> ExitCode {
    match load_model(args) {
        Ok(robot) => {
            out!("{}", to_urdf(&robot));
            ExitCode::SUCCESS
        }
        Err(code) => code,
    }
}

/// `kinserve import-urdf`: the robot file of a URDF's chain, printed as JSON
/// (checked as `kinserve validate` checks a file, so it loads as printed).
fn import_urdf_file(args: &ImportUrdfArgs) -> ExitCode {
    let label = args.file.display().to_string();
    let urdf = match std::fs::read(&args.file) {
        Ok(bytes) => match String::from_utf8(bytes) {
            Ok(text) => text,
            Err(e) => {
                let at = e.utf8_error().valid_up_to();
                eprintln!("{label}: urdf: the document is not UTF-8 (byte {at}): save it as UTF-8");
                return ExitCode::FAILURE;
            }
        },
        Err(e) => {
            eprintln!("{label}: cannot read it: {e}");
            return ExitCode::FAILURE;
        }
    };
    let req = UrdfImport {
        name: args
            .name
            .clone()
            .unwrap_or_else(|| name_from_file(&args.file)),
        urdf,
        base_link: args.base.clone(),
        tip_link: args.tip.clone(),
        convention: match args.convention {
            ConventionArg::Standard => ConventionSpec::Standard,
            ConventionArg::Modified => ConventionSpec::Modified,
        },
    };
    let checked = import_urdf(&req).map_err(Error::from).and_then(|spec| {
        match Robot::from_spec(spec.clone(), &ModelLimits::default()) {
            Ok(_) => Ok(spec),
            Err(e) => Err(Error::from(e)),
        }
    });
    let spec = match checked {
        Ok(spec) => spec,
        Err(e) => {
            print_error(&label, &e);
            return ExitCode::FAILURE;
        }
    };
    print_json(&spec, ExitCode::SUCCESS)
}

/// A robot name from a file name: the part before the first `.`, lowercased,
/// every character outside `[a-z0-9_-]` made `-`, leading `-`/`_` dropped, at
/// most 64 characters (`robot` if nothing is left).
pub fn name_from_file(path: &std::path::Path) -> String {
    let file = path
        .file_name()
        .map(|f| f.to_string_lossy())
        .unwrap_or_default();
    let stem = file.split('.').next().unwrap_or("");
    let name: String = stem
        .chars()
        .map(|c| c.to_ascii_lowercase())
        .map(|c| {
            if c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_' {
                c
            } else {
                '-'
            }
        })
        .skip_while(|c| *c == '-' || *c == '_')
        .take(64)
        .collect();
    if name.is_empty() {
        "robot".into()
    } else {
        name
    }
}

/// `GET /readyz` over a plain TCP connection (no HTTP client needed in the
/// image), or over TLS when `tls` is set (with the client certificate and
/// key files it holds, if any).
fn healthcheck(
    addr: &str,
    timeout: Duration,
    tls: Option<Option<(&std::path::Path, &std::path::Path)>>,
) -> ExitCode {
    let probe = || -> std::io::Result<bool> {
        let sock = addr
            .to_socket_addrs()?
            .next()
            .ok_or_else(|| std::io::Error::other("address resolves to nothing"))?;
        let s = TcpStream::connect_timeout(&sock, timeout)?;
        s.set_read_timeout(Some(timeout))?;
        s.set_write_timeout(Some(timeout))?;
        match tls {
            None => ask_ready(s, addr),
            Some(client) => {
                let host = addr.rsplit_once(':').map_or(addr, |(h, _)| h);
                let host = host.trim_start_matches('[').trim_end_matches(']');
                let s =
                    crate::tls::probe::connect(s, host, client).map_err(std::io::Error::other)?;
                ask_ready(s, addr)
            }
        }
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

/// Sends `GET /readyz` on `s`; whether the answer is 200.
fn ask_ready(mut s: impl Read + Write, addr: &str) -> std::io::Result<bool> {
    s.write_all(
        format!("GET /readyz HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").as_bytes(),
    )?;
    s.flush()?;
    let mut buf = [0u8; 64];
    let n = s.read(&mut buf)?;
    let head = String::from_utf8_lossy(&buf[..n]);
    Ok(head.starts_with("HTTP/1.1 200") || head.starts_with("HTTP/1.0 200"))
}

#[cfg(test)]
mod tests {
    use super::scalar_lists_on_one_line;

    #[test]
    fn matrices_print_one_row_per_line_and_values_stay_as_printed() {
        let value = serde_json::json!({
            "matrix": [[1.0, -0.0, 0.0, 0.4521], [0.0, 1.0, 0.0, -0.15005]],
            "names": ["a", "b,]"],
            "frames": [{"position": [0.0, 1.0, 2.0]}],
            "empty": []
        });
        let pretty = serde_json::to_string_pretty(&value).unwrap();
        let compact = scalar_lists_on_one_line(&pretty);
        assert!(
            compact.contains("\n    [1.0, -0.0, 0.0, 0.4521],\n"),
            "{compact}"
        );
        assert!(compact.contains("\"names\": [\"a\", \"b,]\"]"), "{compact}");
        assert!(
            compact.contains("\"position\": [0.0, 1.0, 2.0]"),
            "{compact}"
        );
        let back: serde_json::Value = serde_json::from_str(&compact).unwrap();
        assert_eq!(back, value, "only whitespace moved");
    }
}
