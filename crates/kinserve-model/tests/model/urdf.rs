//! URDF export (`to_urdf`) read back with an XML parser and evaluated by a
//! tiny URDF chain evaluator written here from the URDF specification
//! (origin = translation then fixed-axis roll-pitch-yaw `Rz(y)·Ry(p)·Rx(r)`,
//! then the joint motion about/along `axis`, default `1 0 0`): `world → tool`
//! must equal the model's FK at random configurations for every robot in
//! `robots/` and for odd tables (both conventions, mm, base and tool).
//! Tolerance: 1e-9 m on positions, 1e-9 on rotation entries.
//!
//! `pinocchio_loads_every_urdf_with_the_same_fk` repeats the check with
//! Pinocchio where Python can import it (`pip install pin`), and says SKIPPED
//! otherwise (a failure under CI: `kinserve_testkit::skip_unless_ci`).
#![allow(
    clippy::needless_range_loop,
    reason = "matrix code reads best with explicit indices"
)]

use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::Path;

use kinserve_kinematics::JointKind;
use kinserve_model::{LengthUnit, ModelLimits, Robot, load_robot_file, to_urdf};

pub(crate) type M4 = [[f64; 4]; 4];

const TOL: f64 = 1e-9;

pub(crate) fn mul(a: &M4, b: &M4) -> M4 {
    let mut c = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            c[i][j] = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// Translation `t`, then rotation `r` (3×3).
fn homogeneous(r: [[f64; 3]; 3], t: [f64; 3]) -> M4 {
    let mut m = [
        [0.0, 0.0, 0.0, 0.0],
        [0.0; 4],
        [0.0; 4],
        [0.0, 0.0, 0.0, 1.0],
    ];
    for i in 0..3 {
        m[i][..3].copy_from_slice(&r[i]);
        m[i][3] = t[i];
    }
    m
}

/// URDF `rpy`: fixed axes x, y, z in that order, i.e. `Rz(yaw)·Ry(pitch)·Rx(roll)`.
fn rpy_matrix([r, p, y]: [f64; 3]) -> [[f64; 3]; 3] {
    let (sr, cr) = r.sin_cos();
    let (sp, cp) = p.sin_cos();
    let (sy, cy) = y.sin_cos();
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

/// Rotation by `q` about the unit axis `u` (Rodrigues).
fn axis_angle(u: [f64; 3], q: f64) -> [[f64; 3]; 3] {
    let (s, c) = q.sin_cos();
    let v = 1.0 - c;
    let [x, y, z] = u;
    [
        [c + x * x * v, x * y * v - z * s, x * z * v + y * s],
        [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
        [z * x * v - y * s, z * y * v + x * s, c + z * z * v],
    ]
}

#[derive(Debug)]
pub(crate) struct J {
    name: String,
    kind: String,
    parent: String,
    origin: M4,
    axis: [f64; 3],
    limits: Option<(f64, f64)>,
}

fn triple(s: Option<&str>) -> [f64; 3] {
    let v: Vec<f64> = s
        .unwrap_or("0 0 0")
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    [v[0], v[1], v[2]]
}

/// The joints from `world` to `tool`, in chain order.
pub(crate) fn parse_chain(xml: &str) -> Vec<J> {
    let doc = roxmltree::Document::parse(xml).expect("well-formed XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "robot");
    let links: Vec<&str> = root
        .children()
        .filter(|n| n.has_tag_name("link"))
        .map(|n| n.attribute("name").unwrap())
        .collect();
    assert!(
        links.contains(&"world") && links.contains(&"tool"),
        "links {links:?}"
    );
    let mut by_child: HashMap<String, J> = HashMap::new();
    for n in root.children().filter(|n| n.has_tag_name("joint")) {
        let child = |tag: &str| n.children().find(|c| c.has_tag_name(tag));
        let origin = child("origin");
        let xyz = triple(origin.and_then(|o| o.attribute("xyz")));
        let rpy = triple(origin.and_then(|o| o.attribute("rpy")));
        let limits = child("limit").and_then(|l| {
            Some((
                l.attribute("lower")?.parse().ok()?,
                l.attribute("upper")?.parse().ok()?,
            ))
        });
        let j = J {
            name: n.attribute("name").unwrap().into(),
            kind: n.attribute("type").unwrap().into(),
            parent: child("parent").unwrap().attribute("link").unwrap().into(),
            origin: homogeneous(rpy_matrix(rpy), xyz),
            // The specification's axes are unit vectors; readers (Pinocchio,
            // KDL) normalise the ones that are not.
            axis: child("axis").map_or([1.0, 0.0, 0.0], |a| {
                let v = triple(a.attribute("xyz"));
                let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                v.map(|x| x / n)
            }),
            limits,
        };
        let c = child("child")
            .unwrap()
            .attribute("link")
            .unwrap()
            .to_string();
        assert!(
            by_child.insert(c.clone(), j).is_none(),
            "link {c} has two parent joints"
        );
    }
    let mut chain = Vec::new();
    let mut at = "tool".to_string();
    while at != "world" {
        let j = by_child
            .remove(&at)
            .unwrap_or_else(|| panic!("no joint into {at}"));
        at = j.parent.clone();
        chain.push(j);
    }
    assert!(
        by_child.is_empty(),
        "joints off the world-tool chain: {:?}",
        by_child.keys()
    );
    chain.reverse();
    chain
}

/// `world → tool` at joint values `q` (rad, m) for the movable joints in chain order.
pub(crate) fn urdf_fk(chain: &[J], q: &[f64]) -> M4 {
    let mut qs = q.iter();
    let mut t = homogeneous(rpy_matrix([0.0; 3]), [0.0; 3]);
    for j in chain {
        t = mul(&t, &j.origin);
        let motion = match j.kind.as_str() {
            "fixed" => continue,
            "revolute" | "continuous" => {
                homogeneous(axis_angle(j.axis, *qs.next().unwrap()), [0.0; 3])
            }
            "prismatic" => {
                let v = *qs.next().unwrap();
                homogeneous(rpy_matrix([0.0; 3]), j.axis.map(|a| a * v))
            }
            other => panic!("joint type {other}"),
        };
        t = mul(&t, &motion);
    }
    assert!(qs.next().is_none(), "more joint values than movable joints");
    t
}

pub(crate) struct Lcg(pub(crate) u64);

impl Lcg {
    pub(crate) fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

pub(crate) fn robots() -> Vec<Robot> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    files.iter().map(|f| load_robot_file(f).unwrap()).collect()
}

pub(crate) fn scale(robot: &Robot) -> f64 {
    match robot.length_unit() {
        LengthUnit::M => 1.0,
        LengthUnit::Mm => 1e-3,
    }
}

/// Random joint values in the model's units: within limits, else ±π / ±1 unit.
pub(crate) fn random_q(robot: &Robot, rng: &mut Lcg) -> Vec<f64> {
    robot
        .joints()
        .iter()
        .map(|j| {
            let (lo, hi) = j.limits.unwrap_or(if j.kind == JointKind::Prismatic {
                (-1.0, 1.0)
            } else {
                (-PI, PI)
            });
            rng.uniform(lo, hi)
        })
        .collect()
}

/// The URDF of `robot` has the documented structure and its FK equals the model's.
fn check(robot: &Robot, seed: u64) {
    let name = robot.name();
    let chain = parse_chain(&to_urdf(robot));
    let rows: Vec<_> = robot.chain().dh_rows().collect();
    assert_eq!(
        chain.len(),
        rows.len() + 2,
        "{name}: base, one joint per row, tool"
    );
    assert_eq!(
        (chain[0].name.as_str(), chain[0].kind.as_str()),
        ("base_joint", "fixed")
    );
    assert_eq!(chain[chain.len() - 1].kind, "fixed", "{name}: tool joint");
    let mut joints = robot.joints().iter();
    let distinct: std::collections::HashSet<&str> =
        robot.joints().iter().map(|j| j.name.as_str()).collect();
    let unique = distinct.len() == robot.joints().len();
    let s = scale(robot);
    for (row, j) in rows.iter().zip(&chain[1..]) {
        let want = match (row.kind, row.kind != JointKind::Fixed) {
            (JointKind::Fixed, _) => "fixed",
            (JointKind::Prismatic, _) => "prismatic",
            _ => "revolute",
        };
        if row.kind == JointKind::Fixed {
            assert_eq!(j.kind, want, "{name}: {}", j.name);
            continue;
        }
        let mj = joints.next().unwrap();
        if unique {
            assert_eq!(j.name, mj.name, "{name}: joint names");
        }
        match (row.kind, mj.limits) {
            (JointKind::Revolute, None) => assert_eq!(j.kind, "continuous", "{name}: {}", j.name),
            (_, Some((lo, hi))) => {
                assert_eq!(j.kind, want, "{name}: {}", j.name);
                let k = if row.kind == JointKind::Prismatic {
                    s
                } else {
                    1.0
                };
                assert_eq!(
                    j.limits,
                    Some((lo * k, hi * k)),
                    "{name}: {} limits in rad / m",
                    j.name
                );
            }
            (_, None) => assert_eq!(j.kind, want),
        }
    }
    let mut rng = Lcg(seed);
    for _ in 0..100 {
        let q = random_q(robot, &mut rng);
        let q_urdf: Vec<f64> = q
            .iter()
            .zip(robot.joints())
            .map(|(v, j)| {
                if j.kind == JointKind::Prismatic {
                    v * s
                } else {
                    *v
                }
            })
            .collect();
        let got = urdf_fk(&chain, &q_urdf);
        let want = robot.chain().forward(&q, 1.0).matrix();
        for i in 0..3 {
            for k in 0..4 {
                let w = if k == 3 { want[i][k] * s } else { want[i][k] };
                assert!(
                    (got[i][k] - w).abs() <= TOL,
                    "{name}: T[{i}][{k}] URDF {} vs FK {w} at q = {q:?}",
                    got[i][k]
                );
            }
        }
    }
}

#[test]
fn every_shipped_robot_exports_a_urdf_with_its_fk() {
    let robots = robots();
    assert!(robots.len() >= 19);
    for (k, r) in robots.iter().enumerate() {
        check(r, 0x0D0F ^ k as u64);
    }
}

#[test]
fn odd_tables_with_base_tool_mm_and_repeated_names_export_exactly() {
    for convention in ["standard", "modified"] {
        let json = format!(
            r#"{{"name": "odd", "convention": "{convention}", "angle_unit": "deg", "length_unit": "mm",
            "links": [
              {{"name": "j", "joint": "revolute", "a": 10, "alpha": 30, "d": 5, "theta": 15, "limits": [-90, 90]}},
              {{"name": "j", "joint": "prismatic", "a": -4, "alpha": -90, "d": 7, "theta": 40, "limits": [0, 100]}},
              {{"name": "tool_joint", "joint": "fixed", "a": 3, "alpha": 123, "d": -2, "theta": 90}},
              {{"joint": "revolute", "a": 8, "alpha": 0, "d": 0, "theta": -20}},
              {{"name": "a<b&\"c\"", "joint": "revolute", "a": 6, "alpha": 180, "d": 1, "theta": 0}}
            ],
            "base": {{"translation": [100, 200, 300], "rpy": [10, 89.99999, 30]}},
            "tool": {{"translation": [0, 0, 50], "rpy": [0, 0, 45]}}}}"#
        );
        let robot = Robot::from_json(json.as_bytes(), &ModelLimits::default()).unwrap();
        check(&robot, 7);
        let chain = parse_chain(&to_urdf(&robot));
        let names: Vec<&str> = chain.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "base_joint",
                "j",
                "j_2",
                "tool_joint",
                "joint3",
                "a<b&\"c\"",
                "tool_joint_2"
            ],
            "{convention}"
        );
    }
}

#[test]
fn the_document_has_visuals_and_placeholder_dynamics() {
    let robot = robots()
        .into_iter()
        .find(|r| r.name() == "puma560")
        .unwrap();
    let xml = to_urdf(&robot);
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let cylinders = doc
        .descendants()
        .filter(|n| n.has_tag_name("cylinder"))
        .count();
    assert!(cylinders >= 6, "one per joint at least, got {cylinders}");
    for l in doc.descendants().filter(|n| n.has_tag_name("limit")) {
        assert_eq!(l.attribute("effort"), Some("100"));
        assert_eq!(l.attribute("velocity"), Some("1"));
    }
    assert!(xml.starts_with("<?xml version=\"1.0\"?>"));
    assert_eq!(doc.root_element().attribute("name"), Some("puma560"));
}

/// Python with Pinocchio: `KINSERVE_PYTHON`, else `python3`, if it imports `pinocchio`.
pub(crate) fn pinocchio_python() -> Option<String> {
    let python = std::env::var("KINSERVE_PYTHON").unwrap_or_else(|_| "python3".into());
    let ok = std::process::Command::new(&python)
        .args(["-c", "import pinocchio"])
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(python)
}

#[test]
fn pinocchio_loads_every_urdf_with_the_same_fk() {
    let Some(python) = pinocchio_python() else {
        kinserve_testkit::skip_unless_ci(
            "pinocchio_loads_every_urdf_with_the_same_fk",
            "no Python that imports pinocchio",
            "pip install pin, or set KINSERVE_PYTHON; .ci/run installs it",
        );
        return;
    };
    let dir = std::env::temp_dir().join(format!("kinserve-urdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut cases = Vec::new();
    for (k, robot) in robots().iter().enumerate() {
        let path = dir.join(format!("{}.urdf", robot.name()));
        std::fs::write(&path, to_urdf(robot)).unwrap();
        let (s, mut rng) = (scale(robot), Lcg(0x914 ^ k as u64));
        let samples: Vec<serde_json::Value> = (0..20)
            .map(|_| {
                let q = random_q(robot, &mut rng);
                let mut pose = robot.chain().forward(&q, 1.0).matrix();
                for row in pose.iter_mut().take(3) {
                    row[3] *= s;
                }
                let q: Vec<f64> = q
                    .iter()
                    .zip(robot.joints())
                    .map(|(v, j)| {
                        if j.kind == JointKind::Prismatic {
                            v * s
                        } else {
                            *v
                        }
                    })
                    .collect();
                serde_json::json!({"q": q, "pose": pose})
            })
            .collect();
        cases.push(serde_json::json!({"name": robot.name(), "urdf": path, "samples": samples}));
    }
    let cases_file = dir.join("cases.json");
    std::fs::write(&cases_file, serde_json::to_vec(&cases).unwrap()).unwrap();
    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/check-urdf-pinocchio.py");
    let out = std::process::Command::new(python)
        .arg(script)
        .arg(&cases_file)
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{report}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        report.lines().filter(|l| l.ends_with(" ok")).count(),
        cases.len(),
        "{report}"
    );
    eprintln!("{report}");
}

/// A two-row model whose first joint is called `name`.
fn named_joint_model(name: &str) -> String {
    serde_json::json!({
        "name": "odd-names", "convention": "standard",
        "links": [
            {"name": name, "joint": "revolute", "a": 0.5, "alpha": 0, "d": 0, "theta": 0},
            {"joint": "fixed", "a": 0.3, "alpha": 0, "d": 0, "theta": 0}
        ]
    })
    .to_string()
}

#[test]
fn every_accepted_odd_link_name_comes_back_exactly_from_the_xml() {
    let odd = [
        "a<b>&c\"d'e",
        "]]>",
        "--",
        "-",
        "<!-- x -->",
        "&amp;",
        "  spaced  ",
        "Schulter/Gelenk #1",
        "肩関節",
        "\u{1F916}",
        "\u{E000}\u{FFFD}",
        "\u{10FFFD}",
        &"é".repeat(64),
    ];
    for name in odd {
        let robot = Robot::from_json(named_joint_model(name).as_bytes(), &ModelLimits::default())
            .unwrap_or_else(|e| panic!("{name:?} refused: {e}"));
        let chain = parse_chain(&to_urdf(&robot));
        assert_eq!(chain[1].name, name, "the URDF changed the name");
    }
}

#[test]
fn a_name_xml_cannot_carry_is_refused_at_validation_naming_the_field() {
    for name in [
        "a\u{1}b",
        "\u{0}",
        "x\u{1b}[31m",
        "\u{85}",
        "\u{202E}",
        "\u{FFFE}",
        "",
    ] {
        let e = Robot::from_json(named_joint_model(name).as_bytes(), &ModelLimits::default())
            .expect_err(name);
        let kinserve_model::ModelError::Invalid { violations, .. } = &e else {
            panic!("{name:?}: {e:?}");
        };
        assert_eq!(violations.len(), 1, "{violations:?}");
        assert_eq!(violations[0].field, "links[0].name", "{name:?}");
    }
}
