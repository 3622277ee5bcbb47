//! URDF import (`import_urdf`): synthetic chains with axes in every
//! direction (−z, non-unit, parallel, intersecting, prismatic, fixed joints
//! between and around them) and the URDF export of every shipped robot,
//! imported in both conventions, must have the forward kinematics of the
//! URDF itself — evaluated by the independent chain evaluator of `urdf.rs`,
//! written from the URDF specification — to 1e-12 of the chain's size; an
//! import exported and imported again gives the same DH table; and what a DH
//! table cannot hold is refused, naming the element.

use std::f64::consts::FRAC_PI_2;

use kinserve_kinematics::JointKind;
use kinserve_model::{
    ConventionSpec, ModelError, ModelLimits, Robot, RobotSpec, UrdfImport, import_urdf, to_urdf,
};

use super::urdf::{Lcg, M4, parse_chain, random_q, robots, scale, urdf_fk};

const CONVENTIONS: [ConventionSpec; 2] = [ConventionSpec::Standard, ConventionSpec::Modified];

fn request(name: &str, xml: &str, convention: ConventionSpec) -> UrdfImport {
    UrdfImport {
        name: name.into(),
        urdf: xml.into(),
        base_link: None,
        tip_link: None,
        convention,
    }
}

fn robot(spec: RobotSpec) -> Robot {
    Robot::from_spec(spec, &ModelLimits::default()).expect("an import is a valid model")
}

fn max_diff(a: &M4, b: &M4) -> f64 {
    (0..3)
        .flat_map(|i| (0..4).map(move |j| (i, j)))
        .map(|(i, j)| (a[i][j] - b[i][j]).abs())
        .fold(0.0, f64::max)
}

/// A URDF chain `world → l1 → … → tool` of `n` joints drawn by `rng`, with
/// the special axes each case asks for.
fn synthetic(rng: &mut Lcg, n: usize, case: usize) -> String {
    let mut joints = String::new();
    let r = |rng: &mut Lcg, s: f64| rng.uniform(-s, s);
    for i in 0..n {
        let kind = match (case + i) % 7 {
            0 | 3 => "revolute",
            1 | 5 => "continuous",
            2 => "prismatic",
            4 => "fixed",
            _ => "revolute",
        };
        let (xyz, rpy, axis) = match case % 4 {
            // General: any origin, any orientation, a non-unit axis.
            0 => (
                [r(rng, 0.5), r(rng, 0.5), r(rng, 0.5)],
                [r(rng, 3.1), r(rng, 3.1), r(rng, 3.1)],
                [r(rng, 2.0), r(rng, 2.0), r(rng, 2.0) + 0.1],
            ),
            // Parallel axes (no rotation), along −z.
            1 => (
                [r(rng, 0.5), r(rng, 0.5), r(rng, 0.2)],
                [0.0; 3],
                [0.0, 0.0, -3.0],
            ),
            // Intersecting axes (no offset), turned by quarter turns.
            2 => (
                [0.0; 3],
                [FRAC_PI_2 * (i % 3) as f64, 0.0, 0.0],
                [0.0, 1.0, 0.0],
            ),
            // A UR-like mix: offsets along one axis, quarter-turn twists.
            _ => (
                [
                    0.0,
                    if i % 2 == 0 { 0.1 } else { 0.0 },
                    0.4 * (i % 2) as f64,
                ],
                [if i % 3 == 0 { FRAC_PI_2 } else { 0.0 }, 0.0, 0.0],
                [0.0, 0.0, 1.0],
            ),
        };
        let parent = if i == 0 {
            "world".to_string()
        } else {
            format!("l{i}")
        };
        let child = if i + 1 == n {
            "tool".to_string()
        } else {
            format!("l{}", i + 1)
        };
        let limit = match kind {
            "revolute" => r#"<limit lower="-2.5" upper="2.5" effort="1" velocity="1"/>"#,
            "prismatic" => r#"<limit lower="-0.3" upper="0.4" effort="1" velocity="1"/>"#,
            _ => "",
        };
        joints.push_str(&format!(
            r#"<joint name="j{i}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>
<origin xyz="{} {} {}" rpy="{} {} {}"/><axis xyz="{} {} {}"/>{limit}</joint>
"#,
            xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2], axis[0], axis[1], axis[2]
        ));
    }
    let links: String = (1..n).map(|i| format!(r#"<link name="l{i}"/>"#)).collect();
    format!(
        r#"<robot name="synthetic"><link name="world"/>{links}<link name="tool"/>{joints}</robot>"#
    )
}

#[test]
fn synthetic_chains_import_with_the_urdfs_own_fk_in_both_conventions() {
    let mut rng = Lcg(0x51);
    let mut checked = 0;
    for case in 0..40 {
        let n = 2 + case % 7;
        let xml = synthetic(&mut rng, n, case);
        let chain = parse_chain(&xml);
        for convention in CONVENTIONS {
            let spec = import_urdf(&request("syn", &xml, convention))
                .unwrap_or_else(|e| panic!("case {case} {convention:?}: {e}\n{xml}"));
            let robot = robot(spec);
            for _ in 0..20 {
                let q = random_q(&robot, &mut rng);
                let got = robot.chain().forward(&q, 1.0).matrix();
                let e = max_diff(&got, &urdf_fk(&chain, &q));
                assert!(
                    e <= 1e-12 * 2.0,
                    "case {case} {convention:?}: off by {e:e}\n{xml}"
                );
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 40 * 2 * 20);
}

#[test]
fn every_shipped_robot_comes_back_from_its_urdf_export() {
    for original in robots() {
        let s = scale(&original);
        let xml = to_urdf(&original);
        for convention in CONVENTIONS {
            let name = original.name();
            let imported = robot(import_urdf(&request(name, &xml, convention)).unwrap());
            assert_eq!(imported.dof(), original.dof(), "{name}");
            let mut rng = Lcg(0x77);
            for _ in 0..20 {
                let q = random_q(&original, &mut rng);
                let q_m: Vec<f64> = q
                    .iter()
                    .zip(original.joints())
                    .map(|(v, j)| {
                        if j.kind == JointKind::Prismatic {
                            v * s
                        } else {
                            *v
                        }
                    })
                    .collect();
                let mut want = original.chain().forward(&q, 1.0).matrix();
                for row in want.iter_mut().take(3) {
                    row[3] *= s;
                }
                let got = imported.chain().forward(&q_m, 1.0).matrix();
                let size = want
                    .iter()
                    .take(3)
                    .map(|r| r[3].abs())
                    .sum::<f64>()
                    .max(1.0);
                let e = max_diff(&got, &want);
                assert!(e <= 1e-12 * size, "{name} {convention:?}: off by {e:e}");
            }
        }
    }
}

/// Joint values and table numbers of two imports agree to `tol`.
fn same_table(a: &RobotSpec, b: &RobotSpec, tol: f64) -> bool {
    a.links.len() == b.links.len()
        && a.links.iter().zip(&b.links).all(|(x, y)| {
            x.joint == y.joint
                && x.name == y.name
                && x.limits == y.limits
                && [
                    (x.a, y.a),
                    (x.alpha, y.alpha),
                    (x.d, y.d),
                    (x.theta, y.theta),
                ]
                .iter()
                .all(|(u, v)| (u - v).abs() <= tol)
        })
}

#[test]
fn import_export_import_gives_the_same_table() {
    let mut rng = Lcg(0x99);
    for case in 0..16 {
        let xml = synthetic(&mut rng, 3 + case % 5, case);
        for convention in CONVENTIONS {
            let first = import_urdf(&request("rt", &xml, convention)).unwrap();
            let again = to_urdf(&robot(first.clone()));
            let second = import_urdf(&request("rt", &again, convention)).unwrap();
            assert!(
                same_table(&first, &second, 1e-12),
                "case {case} {convention:?}:\n{first:#?}\n{second:#?}"
            );
        }
    }
}

fn refused(xml: &str, base: Option<&str>, tip: Option<&str>) -> (String, String) {
    let req = UrdfImport {
        base_link: base.map(Into::into),
        tip_link: tip.map(Into::into),
        ..request("bad", xml, ConventionSpec::Standard)
    };
    match import_urdf(&req) {
        Ok(spec) => panic!("accepted: {spec:?}"),
        Err(e) => {
            let v = e.violations();
            let field = v.first().map(|v| v.field.clone()).unwrap_or_default();
            (field, e.to_string())
        }
    }
}

const TWO_FINGERS: &str = r#"<robot name="g"><link name="base"/><link name="palm"/><link name="left"/><link name="right"/>
<joint name="wrist" type="revolute"><parent link="base"/><child link="palm"/><axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>
<joint name="finger_joint" type="prismatic"><parent link="palm"/><child link="left"/><axis xyz="1 0 0"/><limit lower="0" upper="0.04"/></joint>
<joint name="right_finger" type="prismatic"><parent link="palm"/><child link="right"/><axis xyz="-1 0 0"/><limit lower="0" upper="0.04"/><mimic joint="finger_joint"/></joint>
</robot>"#;

#[test]
fn what_a_dh_table_cannot_hold_is_refused_naming_it() {
    let (field, msg) = refused(TWO_FINGERS, None, None);
    assert_eq!(field, "tip_link");
    assert!(
        msg.contains("'left'") && msg.contains("'right'"),
        "the leaves are listed: {msg}"
    );
    let (field, msg) = refused(TWO_FINGERS, None, Some("right"));
    assert_eq!(field, "urdf");
    assert!(
        msg.contains("'right_finger' mimics 'finger_joint'") && msg.contains("tip link above"),
        "{msg}"
    );
    let (_, msg) = refused(TWO_FINGERS, Some("palm"), Some("base"));
    assert!(msg.contains("not below"), "{msg}");
    let (field, msg) = refused(TWO_FINGERS, None, Some("elbow"));
    assert_eq!(field, "tip_link");
    assert!(
        msg.contains("no link 'elbow'") && msg.contains("'palm'"),
        "{msg}"
    );
    let floating = TWO_FINGERS.replace(
        r#"name="wrist" type="revolute""#,
        r#"name="wrist" type="floating""#,
    );
    let (_, msg) = refused(&floating, None, Some("left"));
    assert!(msg.contains("'wrist' is floating"), "{msg}");
    let planar = TWO_FINGERS.replace(
        r#"name="wrist" type="revolute""#,
        r#"name="wrist" type="planar""#,
    );
    assert!(
        refused(&planar, None, Some("left"))
            .1
            .contains("'wrist' is planar")
    );
    let (_, msg) = refused("<html><body/></html>", None, None);
    assert!(msg.contains("not URDF") && msg.contains("<html>"), "{msg}");
    let entity = r#"<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><robot name="r">&x;</robot>"#;
    let (_, msg) = refused(entity, None, None);
    assert!(
        msg.contains("not a readable XML document"),
        "external entities are refused: {msg}"
    );
    let two_parents = TWO_FINGERS.replace(r#"<child link="right"/>"#, r#"<child link="left"/>"#);
    assert!(
        refused(&two_parents, None, None)
            .1
            .contains("two parent joints")
    );
    let fixed_only = r#"<robot name="f"><link name="a"/><link name="b"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#;
    assert!(
        refused(fixed_only, None, None)
            .1
            .contains("no movable joint")
    );
    let bad_axis = TWO_FINGERS.replace(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0 0"/>"#);
    assert!(
        refused(&bad_axis, None, Some("left"))
            .1
            .contains("zero vector")
    );
}

#[test]
fn the_imported_model_keeps_names_limits_and_units() {
    let spec = import_urdf(&UrdfImport {
        tip_link: Some("left".into()),
        ..request("gripper", TWO_FINGERS, ConventionSpec::Modified)
    })
    .unwrap();
    let names: Vec<_> = spec.links.iter().map(|l| l.name.clone().unwrap()).collect();
    assert_eq!(names, ["wrist", "finger_joint"]);
    assert_eq!(spec.links[0].limits, Some([-1.0, 1.0]));
    assert_eq!(spec.links[1].limits, Some([0.0, 0.04]));
    assert_eq!(spec.angle_unit, kinserve_model::AngleUnit::Rad);
    assert_eq!(spec.length_unit, kinserve_model::LengthUnit::M);
    let _: ModelError =
        import_urdf(&request("x", "not xml", ConventionSpec::Standard)).unwrap_err();
}

/// The arms of example-robot-data imported here: (case, file, base, tip).
const MAKERS_URDFS: [(&str, &str, &str, &str); 7] = [
    (
        "ur3",
        "ur_description/urdf/ur3_robot.urdf",
        "world",
        "tool0",
    ),
    (
        "ur5",
        "ur_description/urdf/ur5_robot.urdf",
        "world",
        "tool0",
    ),
    (
        "ur10",
        "ur_description/urdf/ur10_robot.urdf",
        "world",
        "tool0",
    ),
    (
        "panda",
        "panda_description/urdf/panda.urdf",
        "panda_link0",
        "panda_hand_tcp",
    ),
    (
        "kinova",
        "kinova_description/robots/kinova.urdf",
        "base",
        "j2s6s200_end_effector",
    ),
    (
        "baxter_left",
        "baxter_description/urdf/baxter.urdf",
        "base",
        "left_hand_link",
    ),
    (
        "baxter_right",
        "baxter_description/urdf/baxter.urdf",
        "base",
        "right_hand_link",
    ),
];

fn run_python(python: &str, args: &[&std::ffi::OsStr]) -> std::process::Output {
    std::process::Command::new(python)
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn makers_urdfs_import_in_both_conventions_with_pinocchios_fk() {
    let Some(python) = super::urdf::pinocchio_python() else {
        kinserve_testkit::skip_unless_ci(
            "makers_urdfs_import_in_both_conventions_with_pinocchios_fk",
            "no Python that imports pinocchio",
            "pip install pin example-robot-data, or set KINSERVE_PYTHON; .ci/run installs them",
        );
        return;
    };
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scripts/check-urdf-import-pinocchio.py");
    let out = run_python(&python, &[script.as_os_str(), "--robots-dir".as_ref()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = std::path::PathBuf::from(String::from_utf8(out.stdout).unwrap().trim());
    let mut cases = Vec::new();
    for (name, file, base, tip) in MAKERS_URDFS {
        let path = dir.join(file);
        let xml = std::fs::read_to_string(&path).unwrap();
        for convention in CONVENTIONS {
            let spec = import_urdf(&UrdfImport {
                base_link: Some(base.into()),
                tip_link: Some(tip.into()),
                ..request(name, &xml, convention)
            })
            .unwrap_or_else(|e| panic!("{name} {convention:?}: {e}"));
            let joints: Vec<String> = spec.links.iter().map(|l| l.name.clone().unwrap()).collect();
            let robot = robot(spec);
            let mut rng = Lcg(0x5eed);
            let samples: Vec<serde_json::Value> = (0..50)
                .map(|_| {
                    let q = random_q(&robot, &mut rng);
                    let pose = robot.chain().forward(&q, 1.0).matrix();
                    serde_json::json!({"q": q, "pose": pose})
                })
                .collect();
            cases.push(serde_json::json!({
                "name": format!("{name} {convention:?}"), "urdf": path, "base": base, "tip": tip,
                "joints": joints, "samples": samples,
            }));
        }
    }
    let file =
        std::env::temp_dir().join(format!("kinserve-urdf-import-{}.json", std::process::id()));
    std::fs::write(&file, serde_json::to_vec(&cases).unwrap()).unwrap();
    let out = run_python(&python, &[script.as_os_str(), file.as_os_str()]);
    let _ = std::fs::remove_file(&file);
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{report}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        report.lines().filter(|l| l.ends_with(" ok")).count(),
        14,
        "{report}"
    );
    eprintln!("{report}");
}

#[test]
fn an_unknown_base_and_a_chain_over_the_model_limits_are_refused_before_converting() {
    let (field, msg) = refused(TWO_FINGERS, Some("pedestal"), None);
    assert_eq!(field, "base_link");
    assert!(msg.contains("no link 'pedestal'"), "{msg}");
    let mut rng = Lcg(7);
    let long = synthetic(&mut rng, 12, 1);
    let limits = ModelLimits {
        max_joints: 4,
        max_links: 256,
    };
    let e = kinserve_model::import_urdf_with(
        &request("long", &long, ConventionSpec::Standard),
        &limits,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("more than a model may have (4)"),
        "{e}"
    );
}

/// Imported arms are classified for analytic IK like the built-ins they
/// came from (the class is read off the chain's axes, whatever the frames).
#[test]
fn imported_arms_get_the_analytic_ik_class_of_their_source() {
    use kinserve_kinematics::analytic_ik::AnalyticIk;
    let mut classified = 0;
    for original in robots() {
        let Ok(source) = AnalyticIk::new(original.chain()) else {
            continue;
        };
        classified += 1;
        for convention in CONVENTIONS {
            let name = original.name();
            let imported =
                robot(import_urdf(&request(name, &to_urdf(&original), convention)).unwrap());
            let class = AnalyticIk::new(imported.chain()).map(|a| a.class());
            assert_eq!(class.ok(), Some(source.class()), "{name} {convention:?}");
        }
    }
    assert!(
        classified >= 9,
        "PUMA, IRB 140, KR 5, inline_6dof and the five URs: {classified}"
    );
}
