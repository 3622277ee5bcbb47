//! The closed forms (`ClosedForm::of`) against forward kinematics and against
//! the course notes.
//!
//! A tiny reader of the documented `text` grammar (below) expands each entry
//! into a polynomial over identifiers; evaluating it with the joint values and
//! `symbols` must give the product of the numeric link matrices
//! (`kinserve_kinematics::link_transform`) for every robot in `robots/` at 200
//! random configurations, to 1e-12 (rotation entries, unitless) and
//! 1e-12 · max(1, reach) on positions (model length unit). The same expanded
//! polynomials compare the printed forms with the notes' forms term by term.
#![allow(
    clippy::needless_range_loop,
    reason = "matrix code reads best with explicit indices"
)]

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::Path;
use std::time::{Duration, Instant};

use kinserve_kinematics::{JointKind, Transform, link_transform};
use kinserve_model::{ClosedForm, ModelError, ModelLimits, Robot, load_robot_file};

/// Configurations per robot.
const N: usize = 200;
/// Absolute on rotation entries; relative to max(1, reach) on positions.
const TOL: f64 = 1e-12;

// ------------------------------------------------------------------ reader

/// A polynomial: sorted identifier lists to coefficients.
type Poly = BTreeMap<Vec<String>, f64>;

fn add_into(p: &mut Poly, q: &Poly, sign: f64) {
    for (m, k) in q {
        *p.entry(m.clone()).or_insert(0.0) += sign * k;
    }
    p.retain(|_, k| *k != 0.0);
}

fn mul(p: &Poly, q: &Poly) -> Poly {
    let mut out = Poly::new();
    for (m1, k1) in p {
        for (m2, k2) in q {
            let mut m: Vec<String> = m1.iter().chain(m2).cloned().collect();
            m.sort();
            *out.entry(m).or_insert(0.0) += k1 * k2;
        }
    }
    out.retain(|_, k| *k != 0.0);
    out
}

/// Recursive-descent reader of `expr = ["-"] term {("+"|"-") term}`,
/// `term = factor {("*"|"/") factor}`, `factor = number | identifier | "(" expr ")"`.
struct Reader<'a> {
    s: &'a [u8],
    i: usize,
}

impl Reader<'_> {
    fn parse(text: &str) -> Poly {
        let mut r = Reader {
            s: text.as_bytes(),
            i: 0,
        };
        let p = r.expr();
        r.skip();
        assert_eq!(r.i, r.s.len(), "trailing input in {text:?}");
        p
    }
    fn skip(&mut self) {
        while self.s.get(self.i) == Some(&b' ') {
            self.i += 1;
        }
    }
    fn eat(&mut self, c: u8) -> bool {
        self.skip();
        let hit = self.s.get(self.i) == Some(&c);
        self.i += usize::from(hit);
        hit
    }
    fn expr(&mut self) -> Poly {
        let neg = self.eat(b'-');
        let mut p = Poly::new();
        add_into(&mut p, &self.term(), if neg { -1.0 } else { 1.0 });
        loop {
            if self.eat(b'+') {
                let t = self.term();
                add_into(&mut p, &t, 1.0);
            } else if self.eat(b'-') {
                let t = self.term();
                add_into(&mut p, &t, -1.0);
            } else {
                return p;
            }
        }
    }
    fn term(&mut self) -> Poly {
        let mut p = self.factor();
        loop {
            if self.eat(b'*') {
                p = mul(&p, &self.factor());
            } else if self.eat(b'/') {
                let d = self.factor();
                let k = d.get(&Vec::new()).copied().filter(|_| d.len() == 1);
                let k = k.expect("this reader divides by numbers only");
                p = mul(&p, &Poly::from([(Vec::new(), 1.0 / k)]));
            } else {
                return p;
            }
        }
    }
    fn factor(&mut self) -> Poly {
        if self.eat(b'(') {
            let p = self.expr();
            assert!(self.eat(b')'), "missing ')'");
            return p;
        }
        self.skip();
        let start = self.i;
        while self
            .s
            .get(self.i)
            .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_' || *c == b'.')
        {
            self.i += 1;
        }
        let tok = std::str::from_utf8(&self.s[start..self.i]).unwrap();
        assert!(!tok.is_empty(), "expected a factor at {start}");
        match tok.parse::<f64>() {
            Ok(0.0) => Poly::new(),
            Ok(k) => Poly::from([(Vec::new(), k)]),
            Err(_) => Poly::from([(vec![tok.to_string()], 1.0)]),
        }
    }
}

/// Value of an identifier: `cI`/`sI` from the joint angles, prismatic `dI`
/// from the joint values, everything else from `symbols`.
struct Env<'a> {
    theta: Vec<f64>,
    slide: Vec<Option<f64>>,
    symbols: &'a BTreeMap<String, f64>,
    separated: bool,
}

impl Env<'_> {
    fn value(&self, id: &str) -> f64 {
        if let Some(v) = self.symbols.get(id) {
            return *v;
        }
        let (head, rest) = id.split_at(1);
        let rows: Vec<usize> = if self.separated {
            rest.split('_').filter_map(|r| r.parse().ok()).collect()
        } else {
            rest.chars()
                .filter_map(|c| c.to_digit(10).map(|d| d as usize))
                .collect()
        };
        assert!(
            !rows.is_empty() && rest.chars().all(|c| c.is_ascii_digit() || c == '_'),
            "unknown identifier {id}"
        );
        let sum: f64 = rows.iter().map(|&j| self.theta[j - 1]).sum();
        match head {
            "c" => sum.cos(),
            "s" => sum.sin(),
            "d" if rows.len() == 1 => {
                self.slide[rows[0] - 1].unwrap_or_else(|| panic!("{id} is not a variable"))
            }
            _ => panic!("unknown identifier {id}"),
        }
    }
    fn eval(&self, p: &Poly) -> f64 {
        p.iter()
            .map(|(m, k)| k * m.iter().map(|id| self.value(id)).product::<f64>())
            .sum()
    }
}

// ------------------------------------------------------------------ sampling

struct Lcg(u64);

impl Lcg {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn robots() -> Vec<Robot> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|f| load_robot_file(f).unwrap_or_else(|e| panic!("{}: {e}", f.display())))
        .collect()
}

fn load(name: &str) -> Robot {
    let f = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../robots/{name}.json"));
    load_robot_file(&f).unwrap()
}

/// Size of the arm in its length unit (sum of |a|, |d| and prismatic strokes), at least 1.
fn reach(robot: &Robot) -> f64 {
    let rows: f64 = robot.chain().dh_rows().map(|r| r.a.abs() + r.d.abs()).sum();
    let strokes: f64 = robot
        .joints()
        .iter()
        .filter(|j| j.kind == JointKind::Prismatic)
        .map(|j| j.limits.map_or(1.0, |(lo, hi)| lo.abs().max(hi.abs())))
        .sum();
    (rows + strokes).max(1.0)
}

fn random_q(robot: &Robot, rng: &mut Lcg) -> Vec<f64> {
    robot
        .joints()
        .iter()
        .map(|j| {
            let (lo, hi) = j.limits.unwrap_or(match j.kind {
                JointKind::Prismatic => (-1.0, 1.0),
                _ => (-PI, PI),
            });
            rng.uniform(lo, hi)
        })
        .collect()
}

fn env<'a>(robot: &Robot, cf: &'a ClosedForm, q: &[f64]) -> Env<'a> {
    let mut qs = q.iter();
    let (mut theta, mut slide) = (Vec::new(), Vec::new());
    for r in robot.chain().dh_rows() {
        let v = if r.kind == JointKind::Fixed {
            0.0
        } else {
            *qs.next().unwrap()
        };
        theta.push(
            r.theta
                + if r.kind == JointKind::Revolute {
                    v
                } else {
                    0.0
                },
        );
        slide.push((r.kind == JointKind::Prismatic).then_some(r.d + v));
    }
    Env {
        theta,
        slide,
        symbols: &cf.symbols,
        separated: robot.chain().rows() >= 10,
    }
}

fn assert_text_is(what: &str, text: &[Vec<String>], env: &Env, want: &Transform, reach: f64) {
    let m = want.matrix();
    assert_eq!(text.len(), 4, "{what}: 4 rows");
    for i in 0..4 {
        for j in 0..4 {
            let got = env.eval(&Reader::parse(&text[i][j]));
            let tol = if j == 3 { TOL * reach } else { TOL };
            assert!(
                (got - m[i][j]).abs() <= tol,
                "{what}[{i}][{j}] = {:?} gives {got}, FK {}",
                text[i][j],
                m[i][j]
            );
        }
    }
}

/// Every closed form of `robot` against the numeric product at `N` configurations.
fn check_against_fk(robot: &Robot, seed: u64) {
    let cf = ClosedForm::of(robot).unwrap_or_else(|e| panic!("{}: {e}", robot.name()));
    let chain = robot.chain();
    let rows: Vec<_> = chain.dh_rows().collect();
    assert_eq!(
        cf.link_transforms.len(),
        rows.len(),
        "{}: one A_i per row",
        robot.name()
    );
    let (reach, mut rng) = (reach(robot), Lcg(seed));
    for _ in 0..N {
        let q = random_q(robot, &mut rng);
        let env = env(robot, &cf, &q);
        let mut qs = q.iter();
        let mut t = Transform::IDENTITY;
        for (i, r) in rows.iter().enumerate() {
            let v = if r.kind == JointKind::Fixed {
                0.0
            } else {
                *qs.next().unwrap()
            };
            let a = link_transform(chain.convention(), r, v);
            assert_text_is(
                &format!("{} A_{}", robot.name(), i + 1),
                &cf.link_transforms[i].text,
                &env,
                &a,
                reach,
            );
            t = t.compose(&a);
        }
        assert_text_is(
            &format!("{} 0T{}", robot.name(), rows.len()),
            &cf.transform.text,
            &env,
            &t,
            reach,
        );
        // base · 0Tn · tool is the robot's FK.
        let tool = cf
            .tool
            .map_or(Transform::IDENTITY, |m| Transform::from_matrix(&m));
        let full = Transform::from_matrix(&cf.base).compose(&t).compose(&tool);
        let fk = chain.forward(&q, 1.0);
        assert!(
            full.max_abs_diff(&fk) <= TOL * reach,
            "{}: base·T·tool != FK",
            robot.name()
        );
    }
}

#[test]
fn every_shipped_robot_text_evaluates_to_its_fk() {
    let robots = robots();
    assert!(robots.len() >= 19, "robots/ holds the shipped models");
    for (k, robot) in robots.iter().enumerate() {
        check_against_fk(robot, 0xC105ED ^ k as u64);
    }
}

/// Expanded polynomial of each entry of a 3×4 block written in the grammar.
fn expand(rows: [[&str; 4]; 3]) -> Vec<Vec<Poly>> {
    rows.iter()
        .map(|r| r.iter().map(|e| Reader::parse(e)).collect())
        .collect()
}

/// The printed `⁰Tₙ` of `name` has the same terms as the notes' form `want`
/// (same identifiers, no expanded angle sums left), and the symbols `want_symbols`.
fn assert_notes_form(name: &str, want: [[&str; 4]; 3], want_symbols: &[(&str, f64)]) {
    let cf = ClosedForm::of(&load(name)).unwrap();
    let want = expand(want);
    for i in 0..3 {
        for j in 0..4 {
            let got = Reader::parse(&cf.transform.text[i][j]);
            assert_eq!(
                got, want[i][j],
                "{name} 0Tn[{i}][{j}]: printed {:?}",
                cf.transform.text[i][j]
            );
        }
    }
    assert_eq!(
        cf.transform.text[3],
        ["0", "0", "0", "1"],
        "{name}: last row"
    );
    let symbols: Vec<(&str, f64)> = cf.symbols.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    assert_eq!(symbols, want_symbols, "{name}: symbols");
}

#[test]
fn planar_arm_prints_the_lecture_18_form_exactly() {
    // Lecture 18 (002), Example 1: x = a1 cos(θ1) + a2 cos(θ1 + θ2), printed as c1, c12.
    let cf = ClosedForm::of(&load("planar_2dof")).unwrap();
    let want = [
        ["c12", "-s12", "0", "a1*c1 + a2*c12"],
        ["s12", "c12", "0", "a1*s1 + a2*s12"],
        ["0", "0", "1", "0"],
        ["0", "0", "0", "1"],
    ];
    assert_eq!(cf.transform.text, want);
    assert_eq!(cf.link_transforms[0].text[0], ["c1", "-s1", "0", "a1*c1"]);
    assert_eq!(
        cf.symbols,
        BTreeMap::from([("a1".into(), 0.4), ("a2".into(), 0.3)])
    );
    assert_eq!(
        cf.transform.latex,
        "\\begin{bmatrix} c_{12} & -s_{12} & 0 & a_{1} c_{1} + a_{2} c_{12} \\\\ \
         s_{12} & c_{12} & 0 & a_{1} s_{1} + a_{2} s_{12} \\\\ 0 & 0 & 1 & 0 \\\\ 0 & 0 & 0 & 1 \\end{bmatrix}"
    );
    assert!(
        cf.transform
            .mathml
            .starts_with("<math xmlns=\"http://www.w3.org/1998/Math/MathML\" display=\"block\">")
    );
    assert!(
        cf.transform
            .mathml
            .contains("<msub><mi>c</mi><mn>12</mn></msub>")
    );
}

#[test]
fn spatial_3r_prints_the_lecture_13_form() {
    // Lecture 13 (000), ^0T_3 of the 3R arm. Slip in the notes: the second
    // printed copy ("Validation" slide) drops c1 and s1 from p_x and p_y; the
    // first copy, used here, matches the product (see crates/kinserve-kinematics/tests/kinematics/closed_forms.rs).
    assert_notes_form(
        "spatial_3r",
        [
            ["c1*c23", "-c1*s23", "s1", "c1*(a2*c2 + a3*c23)"],
            ["s1*c23", "-s1*s23", "-c1", "s1*(a2*c2 + a3*c23)"],
            ["s23", "c23", "0", "d1 + a2*s2 + a3*s23"],
        ],
        &[("a2", 0.4), ("a3", 0.3), ("d1", 0.3)],
    );
}

#[test]
fn scara_prints_the_corrected_lecture_19_form() {
    // Lecture 19 (003), ^0T_4 of the SCARA. Slip in the notes: r22 is printed
    // -s12 s4 + c12 c4; the product of the link matrices gives -s12 s4 - c12 c4.
    // α2 = 180° makes θ4 turn against θ1 + θ2: the rotation is in cos/sin of
    // θ12 − θ4, which the grammar (sums only) leaves as c12 c4 + s12 s4.
    assert_notes_form(
        "scara_4dof",
        [
            ["c12*c4 + s12*s4", "-c12*s4 + s12*c4", "0", "a1*c1 + a2*c12"],
            ["s12*c4 - c12*s4", "-s12*s4 - c12*c4", "0", "a1*s1 + a2*s12"],
            ["0", "0", "-1", "d1 - d3 - d4"],
        ],
        &[("a1", 0.35), ("a2", 0.25), ("d1", 0.4), ("d4", 0.05)],
    );
}

#[test]
fn alpha_ii_prints_the_lecture_2_8_form_in_mm() {
    // Intro to Robotics 2.8 (001), T_base^tool of the Alpha II, printed there
    // with the numbers 215, 177.8, 129.5 (mm) in place of d1, a2 = a3, d5.
    assert_notes_form(
        "alpha_ii",
        [
            [
                "c1*c234*c5 + s1*s5",
                "-c1*c234*s5 + s1*c5",
                "-c1*s234",
                "c1*(a2*c2 + a3*c23 - d5*s234)",
            ],
            [
                "s1*c234*c5 - c1*s5",
                "-s1*c234*s5 - c1*c5",
                "-s1*s234",
                "s1*(a2*c2 + a3*c23 - d5*s234)",
            ],
            [
                "-s234*c5",
                "s234*s5",
                "-c234",
                "d1 - a2*s2 - a3*s23 - d5*c234",
            ],
        ],
        &[("a2", 177.8), ("a3", 177.8), ("d1", 215.0), ("d5", 129.5)],
    );
}

#[test]
fn craig_rrr_arm_prints_the_lecture_11_form_with_c23() {
    // Manipulator mechanics lecture 11 (004), ^0T_4 in the modified convention:
    // row i holds a_{i-1}, so the lengths are a2 (row 3) and a3 (fixed row 4).
    let cf = ClosedForm::of(&load("articulated_rrr_mdh")).unwrap();
    assert_eq!(cf.transform.text[0][0], "c1*c23");
    assert_notes_form(
        "articulated_rrr_mdh",
        [
            ["c1*c23", "-c1*s23", "-s1", "c1*(a2*c2 + a3*c23)"],
            ["s1*c23", "-s1*s23", "c1", "s1*(a2*c2 + a3*c23)"],
            ["-s23", "-c23", "0", "d1 - a2*s2 - a3*s23"],
        ],
        &[("a2", 0.4), ("a3", 0.35), ("d1", 0.3)],
    );
}

#[test]
fn cylindrical_robot_and_spherical_wrist_print_the_lecture_forms() {
    // Lecture 19 (003): ^0T_3 of the R-P-P robot, d2 and d3 the prismatic variables.
    assert_notes_form(
        "cylindrical_3dof",
        [
            ["c1", "0", "-s1", "-d3*s1"],
            ["s1", "0", "c1", "d3*c1"],
            ["0", "-1", "0", "d1 + d2"],
        ],
        &[("d1", 0.5)],
    );
    // Lecture 13 (000): ^3T_6 of the wrist; the robot file numbers its rows
    // 1-3, so θ4, θ5, θ6, d6 of the notes are θ1, θ2, θ3, d3 here. (Lecture 19's
    // copy of this wrist has two slips, see
    // crates/kinserve-kinematics/tests/kinematics/closed_forms.rs.)
    assert_notes_form(
        "spherical_wrist",
        [
            ["c1*c2*c3 - s1*s3", "-c1*c2*s3 - s1*c3", "c1*s2", "d3*c1*s2"],
            ["s1*c2*c3 + c1*s3", "-s1*c2*s3 + c1*c3", "s1*s2", "d3*s1*s2"],
            ["-s2*c3", "s2*s3", "c2", "d3*c2"],
        ],
        &[("d3", 0.1)],
    );
}

// ------------------------------------------------------------------ other tables

fn model(json: &str) -> Robot {
    Robot::from_json(json.as_bytes(), &ModelLimits::default()).unwrap()
}

#[test]
fn ten_rows_or_more_separate_row_numbers_with_underscores() {
    // 11 revolute rows, all axes parallel: one run, so ⁰T is Rz(θ1 + … + θ11).
    let rows: Vec<String> = (0..11)
        .map(|_| r#"{"joint": "revolute", "a": 0.1, "alpha": 0, "d": 0, "theta": 0}"#.to_string())
        .collect();
    let robot = model(&format!(
        r#"{{"name": "long", "convention": "standard", "links": [{}]}}"#,
        rows.join(",")
    ));
    let cf = ClosedForm::of(&robot).unwrap();
    assert_eq!(cf.transform.text[0][0], "c1_2_3_4_5_6_7_8_9_10_11");
    assert!(
        cf.transform.text[0][3].ends_with("a11*c1_2_3_4_5_6_7_8_9_10_11"),
        "{}",
        cf.transform.text[0][3]
    );
    assert!(
        cf.transform.text[0][3].contains("a10*c1_2_3_4_5_6_7_8_9_10 "),
        "{}",
        cf.transform.text[0][3]
    );
    assert!(cf.transform.latex.contains("c_{1,2,3,4,5,6,7,8,9,10,11}"));
    check_against_fk(&robot, 11);
}

#[test]
fn arbitrary_angles_offsets_and_fixed_rows_get_named_constants() {
    // Constant angles off the 90° grid, θ offsets on revolute joints, a
    // prismatic row with θ and d offsets, a fixed row, base and tool: in both
    // conventions, evaluated against FK like the shipped robots.
    for convention in ["standard", "modified"] {
        let robot = model(&format!(
            r#"{{"name": "odd", "convention": "{convention}", "angle_unit": "deg", "length_unit": "mm",
            "links": [
              {{"joint": "revolute", "a": 10, "alpha": 30, "d": 5, "theta": 15}},
              {{"joint": "prismatic", "a": -4, "alpha": -90, "d": 7, "theta": 40, "limits": [0, 100]}},
              {{"joint": "fixed", "a": 3, "alpha": 123, "d": -2, "theta": 90}},
              {{"joint": "revolute", "a": 8, "alpha": 0, "d": 0, "theta": -20}},
              {{"joint": "revolute", "a": 6, "alpha": 180, "d": 1, "theta": 0}}
            ],
            "base": {{"translation": [1, 2, 3], "rpy": [10, 20, 30]}},
            "tool": {{"translation": [0, 0, 50], "rpy": [0, 0, 45]}}}}"#
        ));
        let cf = ClosedForm::of(&robot).unwrap();
        let has = |s: &str| cf.symbols.contains_key(s);
        assert!(
            has("cos_theta2") && has("sin_theta2"),
            "{convention}: θ2 of the prismatic row is constant: {:?}",
            cf.symbols
        );
        assert!(
            has("cos_alpha3") || has("cos_alpha2"),
            "{convention}: 123° twist is named: {:?}",
            cf.symbols
        );
        assert!(!has("cos_theta3"), "{convention}: θ3 = 90° folds");
        assert!(cf.tool.is_some());
        assert_eq!(
            cf.variables
                .iter()
                .map(|v| v.name.as_str())
                .collect::<Vec<_>>(),
            ["theta1", "d2", "theta4", "theta5"]
        );
        check_against_fk(&robot, 0x0DD);
    }
}

#[test]
fn a_closed_form_too_long_to_print_is_refused_by_field() {
    // 40 revolute rows with alternating twists: the product doubles its terms per row.
    let rows: Vec<String> = (0..40)
        .map(|i| {
            format!(
                r#"{{"joint": "revolute", "a": 0.1, "alpha": {}, "d": 0.1, "theta": 0}}"#,
                if i % 2 == 0 { 90 } else { -90 }
            )
        })
        .collect();
    let robot = model(&format!(
        r#"{{"name": "snake", "convention": "standard", "angle_unit": "deg", "links": [{}]}}"#,
        rows.join(",")
    ));
    let err = ClosedForm::of(&robot).unwrap_err();
    assert_too_large_on_links(&err);
    assert_eq!(ClosedForm::check(&robot).unwrap_err(), err);
}

// ------------------------------------------------------------------ work limit

/// `twisted` revolute rows (α = 0.3 rad, a and d nonzero) in `convention`,
/// then the rows in `tail`, in JSON.
fn twisted_then(convention: &str, twisted: usize, tail: &[&str]) -> Robot {
    let mut rows: Vec<&str> =
        vec![r#"{"joint": "revolute", "a": 0.1, "alpha": 0.3, "d": 0.05, "theta": 0}"#; twisted];
    rows.extend(tail);
    model(&format!(
        r#"{{"name": "twisted", "convention": "{convention}", "links": [{}]}}"#,
        rows.join(",")
    ))
}

const IDENTITY: &str = r#"{"joint": "fixed", "a": 0, "alpha": 0, "d": 0, "theta": 0}"#;

fn assert_too_large_on_links(err: &ModelError) {
    let ModelError::TooLarge { detail, field } = err else {
        panic!("want a too-large error, got {err:?}");
    };
    assert_eq!(field.as_deref(), Some("links"));
    assert!(detail.contains("too large"), "{detail}");
    assert!(
        detail.contains("fewer such rows"),
        "says what to do: {detail}"
    );
}

/// `⁰Tₙ` of `cf` (of `robot`) evaluated at `q`, parsed once per entry.
fn eval_transform(robot: &Robot, cf: &ClosedForm, qs: &[Vec<f64>]) -> Vec<[[f64; 4]; 4]> {
    let parsed: Vec<Vec<Poly>> = cf
        .transform
        .text
        .iter()
        .map(|r| r.iter().map(|e| Reader::parse(e)).collect())
        .collect();
    qs.iter()
        .map(|q| {
            let env = env(robot, cf, q);
            std::array::from_fn(|i| std::array::from_fn(|j| env.eval(&parsed[i][j])))
        })
        .collect()
}

#[test]
fn the_attack_model_of_issue_22_is_refused_fast_as_too_large_on_links() {
    // 8 twisted revolute rows and 248 identity fixed rows (256 rows, the most
    // a model may have): 5.5 s of CPU per request before the work limit.
    let robot = twisted_then("standard", 8, &[IDENTITY; 248]);
    let start = Instant::now();
    let err = ClosedForm::of(&robot).unwrap_err();
    let took = start.elapsed();
    assert_too_large_on_links(&err);
    assert!(err.to_string().contains("operations"), "{err}");
    // Loose, debug build: tells a refusal from a stall, not a benchmark.
    assert!(took < Duration::from_secs(1), "refused after {took:?}");
    assert_eq!(
        ClosedForm::check(&robot).unwrap_err(),
        err,
        "check agrees with of"
    );
}

#[test]
fn identity_rows_change_nothing_and_cost_nothing() {
    // Identity rows at the end, as in the attack, and between the revolute rows.
    let mut rng = Lcg(0x1D);
    for convention in ["standard", "modified"] {
        let plain = twisted_then(convention, 4, &[]);
        let padded = {
            let mut tail = vec![IDENTITY; 3];
            tail.extend([IDENTITY; 200]);
            let mut rows = vec![IDENTITY];
            rows.extend(
                [r#"{"joint": "revolute", "a": 0.1, "alpha": 0.3, "d": 0.05, "theta": 0}"#; 4]
                    .iter()
                    .flat_map(|r| [*r, IDENTITY]),
            );
            rows.extend(tail);
            model(&format!(
                r#"{{"name": "padded", "convention": "{convention}", "links": [{}]}}"#,
                rows.join(",")
            ))
        };
        let (cf_plain, cf_padded) = (
            ClosedForm::of(&plain).unwrap(),
            ClosedForm::of(&padded).unwrap(),
        );
        let qs: Vec<Vec<f64>> = (0..20).map(|_| random_q(&plain, &mut rng)).collect();
        let (want, got) = (
            eval_transform(&plain, &cf_plain, &qs),
            eval_transform(&padded, &cf_padded, &qs),
        );
        for (w, g) in want.iter().zip(&got) {
            for i in 0..4 {
                for j in 0..4 {
                    assert!((w[i][j] - g[i][j]).abs() <= 1e-9, "{convention} [{i}][{j}]");
                }
            }
        }
        // Only their own A_i (four constant 1s each) is printed for the
        // identity rows: nothing enters the product.
        let extra = ClosedForm::check(&padded).unwrap() - ClosedForm::check(&plain).unwrap();
        let identity_rows = (padded.chain().rows() - plain.chain().rows()) as u64;
        assert!(
            extra <= identity_rows * 4 * 32,
            "{convention}: {extra} more operations for {identity_rows} identity rows"
        );
    }
}

#[test]
fn a_run_of_fixed_rows_is_multiplied_into_the_product_once() {
    // 5 twisted revolute rows, then fixed rotations (±90° twists, θ 90°): one
    // row or a run of 40 must cost about the same, and both print the FK.
    const TURN: &str = r#"{"joint": "fixed", "a": 0, "alpha": 1.5707963267948966, "d": 0, "theta": 1.5707963267948966}"#;
    const BACK: &str =
        r#"{"joint": "fixed", "a": 0, "alpha": -1.5707963267948966, "d": 0, "theta": 0}"#;
    let one = twisted_then("standard", 5, &[TURN]);
    let run: Vec<&str> = (0..40)
        .map(|i| if i % 3 == 0 { BACK } else { TURN })
        .collect();
    let many = twisted_then("standard", 5, &run);
    let (w_one, w_many) = (
        ClosedForm::check(&one).unwrap(),
        ClosedForm::check(&many).unwrap(),
    );
    assert!(
        w_many < w_one + w_one / 2,
        "a run of 40 fixed rows costs {w_many} operations, one row {w_one}"
    );
    // Folding keeps the value: runs of twisted fixed rows with lengths between
    // revolute and prismatic rows, against the numeric link product.
    for convention in ["standard", "modified"] {
        let robot = model(&format!(
            r#"{{"name": "runs", "convention": "{convention}", "links": [
              {{"joint": "revolute", "a": 0.3, "alpha": 0, "d": 0.1, "theta": 0.1}},
              {{"joint": "fixed", "a": 0.2, "alpha": 0.7, "d": 0.1, "theta": 0.4}},
              {{"joint": "fixed", "a": 0, "alpha": 0, "d": 0, "theta": 0}},
              {{"joint": "fixed", "a": -0.1, "alpha": 1.5707963267948966, "d": 0.3, "theta": 2.0}},
              {{"joint": "fixed", "a": 0.05, "alpha": 0, "d": 0, "theta": 3.141592653589793}},
              {{"joint": "prismatic", "a": 0.1, "alpha": 1.5707963267948966, "d": 0.2, "theta": 0.3, "limits": [0, 1]}},
              {{"joint": "fixed", "a": 0.1, "alpha": 0, "d": 0.2, "theta": -0.6}},
              {{"joint": "fixed", "a": 0.2, "alpha": 0, "d": 0, "theta": 0}}
            ]}}"#
        ));
        check_against_fk(&robot, 0xF01D);
    }
}

#[test]
fn the_largest_closed_forms_served_stay_under_the_work_limit() {
    // 7 twisted rows are served, 8 are not (standard and modified alike); the
    // work `check` reports is within the documented limit.
    for convention in ["standard", "modified"] {
        let work = ClosedForm::check(&twisted_then(convention, 7, &[])).unwrap();
        assert!(work <= ClosedForm::MAX_WORK, "{convention}: {work}");
        let err = ClosedForm::check(&twisted_then(convention, 8, &[])).unwrap_err();
        assert_too_large_on_links(&err);
    }
}
