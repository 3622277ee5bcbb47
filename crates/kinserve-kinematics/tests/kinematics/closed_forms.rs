//! Closed-form forward kinematics from the course notes (`shared/seeds/` beside the repository)
//! against the library's FK (`RobotExt::fk_unchecked` from kinserve-testkit) for the course robots in
//! `robots/`.
//!
//! Every closed form written here was first checked numerically (numpy, 500
//! random configurations each) against the product of the general link matrices
//! of the notes, which are the authority. Where a printed closed form in the
//! notes disagreed with that product, the corrected form is used and the test
//! says which slip was corrected and how it was found.
//!
//! Sampling: each test evaluates `N_CONFIGS` configurations: a few fixed ones
//! (all joints at zero / at a range end, all at +-pi/2) followed by a
//! deterministic LCG, uniform over the joint ranges (revolute joints without
//! limits in the notes: [-pi, pi]; prismatic joints: the limits of the robot file).
//!
//! Tolerances: `1e-9` absolute on rotation entries (unitless, magnitude <= 1) and
//! `1e-9 * reach` on positions, where `reach` is the size of the arm in its own
//! length unit (sum of |a|, |d| and the largest strokes), i.e. 1e-9 relative to
//! the arm size.
#![allow(
    clippy::needless_range_loop,
    reason = "matrix code reads best with explicit row/column indices"
)]

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

use kinserve_kinematics::{Convention, DhRow, JointKind, Transform, link_transform};
use kinserve_model::{Robot, load_robot_file};
use kinserve_testkit::RobotExt;
use nalgebra::Matrix4;

/// Configurations evaluated per closed form.
const N_CONFIGS: usize = 500;
/// Absolute tolerance on rotation entries, and relative tolerance on positions.
const TOL: f64 = 1e-9;

type M4 = [[f64; 4]; 4];

fn load(name: &str) -> Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(Path::new(&path)).unwrap_or_else(|e| panic!("{path}: not a valid model: {e:?}"))
}

/// Minimal deterministic generator (Knuth's MMIX LCG), uniform doubles in [0, 1).
struct Lcg(u64);

impl Lcg {
    fn next_f64(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

/// Revolute range used when the notes give none.
const REV: (f64, f64) = (-PI, PI);

/// `N_CONFIGS` joint vectors over `ranges`: three fixed ones (each joint at 0
/// clamped into its range, at the upper end, at the lower end), two with every
/// revolute joint at +-pi/2, then an LCG seeded with `seed`.
fn configs(ranges: &[(f64, f64)], seed: u64) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(N_CONFIGS);
    out.push(ranges.iter().map(|&(lo, hi)| 0f64.clamp(lo, hi)).collect());
    out.push(ranges.iter().map(|&(_, hi)| hi).collect());
    out.push(ranges.iter().map(|&(lo, _)| lo).collect());
    for s in [FRAC_PI_2, -FRAC_PI_2] {
        out.push(
            ranges
                .iter()
                .map(|&(lo, hi)| if (lo, hi) == REV { s } else { lo })
                .collect(),
        );
    }
    let mut rng = Lcg(seed);
    while out.len() < N_CONFIGS {
        out.push(ranges.iter().map(|&(lo, hi)| rng.uniform(lo, hi)).collect());
    }
    out
}

/// Compares the upper 3x4 block: rotation within `TOL`, position within `TOL * reach`;
/// also checks that the last row is [0, 0, 0, 1] (within `TOL`).
fn assert_close(got: &M4, want: &M4, reach: f64, what: &str, q: &[f64]) {
    for i in 0..3 {
        for j in 0..3 {
            let e = (got[i][j] - want[i][j]).abs();
            assert!(
                e <= TOL,
                "{what}: R[{i}][{j}] = {} but closed form gives {} (|diff| {e:e} > {TOL:e}) at q = {q:?}",
                got[i][j],
                want[i][j]
            );
        }
        let e = (got[i][3] - want[i][3]).abs();
        assert!(
            e <= TOL * reach,
            "{what}: p[{i}] = {} but closed form gives {} (|diff| {e:e} > {:e}) at q = {q:?}",
            got[i][3],
            want[i][3],
            TOL * reach
        );
    }
    for (j, want) in [0.0, 0.0, 0.0, 1.0].into_iter().enumerate() {
        // Exact for the library's transforms; a numeric inverse may be off by an ulp.
        assert!(
            (got[3][j] - want).abs() <= TOL,
            "{what}: last row {:?} at q = {q:?}",
            got[3]
        );
    }
}

fn to_na(m: &M4) -> Matrix4<f64> {
    Matrix4::from_fn(|i, j| m[i][j])
}

fn from_na(m: &Matrix4<f64>) -> M4 {
    let mut out = [[0.0; 4]; 4];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = m[(i, j)];
        }
    }
    out
}

fn sc(x: f64) -> (f64, f64) {
    (x.sin(), x.cos())
}

// ---------------------------------------------------------------------------
// Lecture 18 (002): 2-DoF planar arm. robots/planar_2dof.json: a1 = 0.4, a2 = 0.3 m.

#[test]
fn planar_2dof_matches_lecture_closed_form() {
    const A1: f64 = 0.4;
    const A2: f64 = 0.3;
    let robot = load("planar_2dof");
    for q in configs(&[REV, REV], 0x2D0F) {
        let (s1, c1) = sc(q[0]);
        let (s12, c12) = sc(q[0] + q[1]);
        // ^0T_2 of lecture 18: x = a1 c1 + a2 c12, y = a1 s1 + a2 s12, z = 0,
        // orientation Rz(theta1 + theta2).
        let want = [
            [c12, -s12, 0.0, A1 * c1 + A2 * c12],
            [s12, c12, 0.0, A1 * s1 + A2 * s12],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        assert_close(
            &robot.fk_unchecked(&q).matrix(),
            &want,
            A1 + A2,
            "planar_2dof ^0T_2",
            &q,
        );
    }
}

// ---------------------------------------------------------------------------
// Lecture 13 (000): spatial 3R arm. robots/spatial_3r.json: d1 = 0.3, a2 = 0.4, a3 = 0.3 m.

#[test]
fn spatial_3r_matches_lecture_closed_form() {
    const D1: f64 = 0.3;
    const A2: f64 = 0.4;
    const A3: f64 = 0.3;
    let robot = load("spatial_3r");
    for q in configs(&[REV, REV, REV], 0x3A3A) {
        let (s1, c1) = sc(q[0]);
        let (s2, c2) = sc(q[1]);
        let (s23, c23) = sc(q[1] + q[2]);
        // Slip corrected: the notes print ^0T_3 twice; one copy (the second
        // "Validation" slide) drops the factors c1 and s1 from p_x and p_y, i.e.
        // p_x = p_y = a2 c2 + a3 c23. Found by comparing both printed copies with
        // the product ^0A_1 ^1A_2 ^2A_3 numerically: only the copy with
        // p_x = c1 (a2 c2 + a3 c23), p_y = s1 (a2 c2 + a3 c23) matches (the other
        // is off by up to 1.4 m with these dimensions), which is the form used here.
        let r = A2 * c2 + A3 * c23;
        let want = [
            [c1 * c23, -c1 * s23, s1, c1 * r],
            [s1 * c23, -s1 * s23, -c1, s1 * r],
            [s23, c23, 0.0, D1 + A2 * s2 + A3 * s23],
            [0.0, 0.0, 0.0, 1.0],
        ];
        assert_close(
            &robot.fk_unchecked(&q).matrix(),
            &want,
            D1 + A2 + A3,
            "spatial_3r ^0T_3",
            &q,
        );
    }
}

// ---------------------------------------------------------------------------
// Lecture 13 (000) / lecture 19 (003): spherical wrist. robots/spherical_wrist.json: d6 = 0.1 m.

/// ^3T_6 of the spherical wrist (alpha = -90, +90, 0; d6), as printed in lecture 13.
fn wrist_3t6(t4: f64, t5: f64, t6: f64, d6: f64) -> M4 {
    let (s4, c4) = sc(t4);
    let (s5, c5) = sc(t5);
    let (s6, c6) = sc(t6);
    [
        [
            c4 * c5 * c6 - s4 * s6,
            -c4 * c5 * s6 - s4 * c6,
            c4 * s5,
            c4 * s5 * d6,
        ],
        [
            s4 * c5 * c6 + c4 * s6,
            -s4 * c5 * s6 + c4 * c6,
            s4 * s5,
            s4 * s5 * d6,
        ],
        [-s5 * c6, s5 * s6, c5, c5 * d6],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

#[test]
fn spherical_wrist_matches_lecture_closed_form() {
    const D6: f64 = 0.1;
    let robot = load("spherical_wrist");
    for q in configs(&[REV, REV, REV], 0x3716) {
        // The ^3T_6 of lecture 13 matches the product of its link matrices as
        // printed. Lecture 19 prints the same wrist (joints numbered 1-3, d3)
        // with two slips, not used here: its ^1A_2 (alpha = +90) has the third
        // column (-s2, c2, 0) where the general link matrix gives (s2, -c2, 0),
        // and its ^0T_3 has r21 = s1c2c3 + c1c3 where the product gives
        // s1c2c3 + c1s3. Found by evaluating the printed matrices and the product
        // of general link matrices at random angles (entries differ by up to 2).
        let want = wrist_3t6(q[0], q[1], q[2], D6);
        assert_close(
            &robot.fk_unchecked(&q).matrix(),
            &want,
            D6,
            "spherical_wrist ^3T_6",
            &q,
        );
        // Wrist centre stays at the origin: p = d6 * approach.
        let t = robot.fk_unchecked(&q).matrix();
        for i in 0..3 {
            assert!(
                (t[i][3] - D6 * t[i][2]).abs() <= TOL * D6,
                "wrist: p != d6 * z6 at q = {q:?}"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Lecture 13 (000): inline 6-DoF arm = 3R arm (a3 = 0, alpha3 = 90) + spherical wrist.
// robots/inline_6dof.json: d1 = 0.3, a2 = 0.4, d4 = 0.35, d6 = 0.1 m.

#[test]
fn inline_6dof_is_arm_times_lecture_wrist() {
    const D1: f64 = 0.3;
    const A2: f64 = 0.4;
    const D4: f64 = 0.35;
    const D6: f64 = 0.1;
    let robot = load("inline_6dof");
    for q in configs(&[REV; 6], 0x1D0F6) {
        let (s1, c1) = sc(q[0]);
        let (s2, c2) = sc(q[1]);
        let (s23, c23) = sc(q[1] + q[2]);
        // ^0T_3 of the arm rows 1-3 (0A1 with alpha 90, d1; 1A2 with a2;
        // 2A3 with alpha 90, a3 = 0), derived from the general link matrix and
        // checked numerically against the product.
        let t03 = [
            [c1 * c23, s1, c1 * s23, A2 * c1 * c2],
            [s1 * c23, -c1, s1 * s23, A2 * s1 * c2],
            [s23, 0.0, -c23, D1 + A2 * s2],
            [0.0, 0.0, 0.0, 1.0],
        ];
        // ^3A_4 = Tz(d4) Rz(theta4) Rx(alpha4): with the wrist rows of the wrist
        // table, ^3T_6 = Tz(d4) * (lecture-13 wrist ^3T_6).
        // Slip corrected: the 6-DoF table of lecture 13 prints alpha4 = +90 (and
        // alpha5 = -90), while the spherical-wrist table just before it gives
        // alpha4 = -90, alpha5 = +90, and the lecture says the 6-DoF arm is
        // examples 1 and 2 together with only the z3 change. Found by computing
        // the product of link matrices both ways: with the printed twists the
        // tail differs from the wrist's ^3T_6 (entries off by up to 2); with the
        // wrist-table twists it equals it to 1e-16. The robot file uses -90/+90.
        let mut tail = wrist_3t6(q[3], q[4], q[5], D6);
        tail[2][3] += D4;
        let want = from_na(&(to_na(&t03) * to_na(&tail)));
        let got = robot.fk_unchecked(&q).matrix();
        let reach = D1 + A2 + D4 + D6;
        assert_close(&got, &want, reach, "inline_6dof ^0T_6", &q);
        // Wrist centre = flange - d6 * approach depends on theta1..3 only.
        let wc = [
            c1 * (A2 * c2 + D4 * s23),
            s1 * (A2 * c2 + D4 * s23),
            D1 + A2 * s2 - D4 * c23,
        ];
        for i in 0..3 {
            let e = (got[i][3] - D6 * got[i][2] - wc[i]).abs();
            assert!(
                e <= TOL * reach,
                "inline_6dof wrist centre [{i}] off by {e:e} at q = {q:?}"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Lecture 2.8 (001): Alpha II arm, mm (d1 = 215, a2 = a3 = 177.8, d5 = 129.5).

#[test]
fn alpha_ii_matches_lecture_closed_form() {
    let robot = load("alpha_ii");
    for q in configs(&[REV; 5], 0xA1FA) {
        let (s1, c1) = sc(q[0]);
        let (s2, c2) = sc(q[1]);
        let (s23, c23) = sc(q[1] + q[2]);
        let (s234, c234) = sc(q[1] + q[2] + q[3]);
        let (s5, c5) = sc(q[4]);
        // T_base^tool as printed in lecture 2.8 (verified against the product of
        // the five link matrices; no slip in this matrix). The lecture's partial
        // products T_base^wrist and T_wrist^tool also match. (The slide that
        // expands T_base^wrist prints ^1T_2 with its third row missing, and an
        // earlier slide shows a garbled ^0T_1 with "25"; neither is used here.)
        let r = 177.8 * c2 + 177.8 * c23 - 129.5 * s234;
        let want = [
            [
                c1 * c234 * c5 + s1 * s5,
                -c1 * c234 * s5 + s1 * c5,
                -c1 * s234,
                c1 * r,
            ],
            [
                s1 * c234 * c5 - c1 * s5,
                -s1 * c234 * s5 - c1 * c5,
                -s1 * s234,
                s1 * r,
            ],
            [
                -s234 * c5,
                s234 * s5,
                -c234,
                215.0 - 177.8 * s2 - 177.8 * s23 - 129.5 * c234,
            ],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let got = robot.fk_unchecked(&q).matrix();
        let reach = 215.0 + 177.8 + 177.8 + 129.5;
        assert_close(&got, &want, reach, "alpha_ii T_base^tool", &q);
        // Approach vector (-C1 S234, -S1 S234, -C234), independent of theta5.
        let approach = [-c1 * s234, -s1 * s234, -c234];
        for i in 0..3 {
            assert!(
                (got[i][2] - approach[i]).abs() <= TOL,
                "alpha_ii approach at q = {q:?}"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Lecture 19 (003): cylindrical R-P-P robot. robots/cylindrical_3dof.json:
// d1 = 0.5 m, d2 in [0, 0.6] m, d3 in [0.2, 0.7] m.

const CYL_D1: f64 = 0.5;
const CYL_D2: (f64, f64) = (0.0, 0.6);
const CYL_D3: (f64, f64) = (0.2, 0.7);

#[test]
fn cylindrical_3dof_matches_lecture_closed_form() {
    let robot = load("cylindrical_3dof");
    for q in configs(&[REV, CYL_D2, CYL_D3], 0xC71) {
        let (s1, c1) = sc(q[0]);
        let (d2, d3) = (q[1], q[2]);
        // ^0T_3 of lecture 19: p = (-d3 s1, d3 c1, d1 + d2) (matches the product).
        let want = [
            [c1, 0.0, -s1, -d3 * s1],
            [s1, 0.0, c1, d3 * c1],
            [0.0, -1.0, 0.0, CYL_D1 + d2],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let reach = CYL_D1 + CYL_D2.1 + CYL_D3.1;
        assert_close(
            &robot.fk_unchecked(&q).matrix(),
            &want,
            reach,
            "cylindrical_3dof ^0T_3",
            &q,
        );
    }
}

// ---------------------------------------------------------------------------
// Lecture 19 (003): cylindrical robot with spherical wrist. robots/cylindrical_wrist_6dof.json:
// d1 = 0.5 m, d6 = 0.1 m, strokes as cylindrical_3dof.

#[test]
fn cylindrical_wrist_6dof_matches_corrected_closed_form() {
    const D6: f64 = 0.1;
    let robot = load("cylindrical_wrist_6dof");
    for q in configs(&[REV, CYL_D2, CYL_D3, REV, REV, REV], 0xC716) {
        let (s1, c1) = sc(q[0]);
        let (d2, d3) = (q[1], q[2]);
        let (s4, c4) = sc(q[3]);
        let (s5, c5) = sc(q[4]);
        let (s6, c6) = sc(q[5]);
        // Slips corrected: the expanded ^0T_6 printed in lecture 19 has wrong
        // terms in five rotation entries (r13, r23, r33, r31 and the position are
        // right). As printed -> as the product gives:
        //   r11: c1c4c5c6 - c1c4c6 + s1s5s6   ->  c1c4c5c6 - c1s4s6 + s1s5c6
        //   r21: s1c4c5c6 - s1s4s6 - c1s5s6   ->  s1c4c5c6 - s1s4s6 - c1s5c6
        //   r12: -c1c4c5c6 - c1c4c6 - s1s5s6  -> -c1c4c5s6 - c1s4c6 - s1s5s6
        //   r22: -s1c4c5s6 - s1s4s6 + c1s5c6  -> -s1c4c5s6 - s1s4c6 + c1s5s6
        //   r32: s4c5c6 - c4c6                ->  s4c5s6 - c4c6
        // (swapped s/c indices and a repeated c4/c6 term). Found by evaluating the
        // printed entries against ^0T_3 (cylindrical) * ^3T_6 (wrist) and against
        // the product of the six link matrices at 500 random configurations:
        // exactly these five entries differed (by up to 2.2); the corrected
        // entries agree to 1e-16. The corrected form is R03 * R36 expanded.
        let want = [
            [
                c1 * c4 * c5 * c6 - c1 * s4 * s6 + s1 * s5 * c6,
                -c1 * c4 * c5 * s6 - c1 * s4 * c6 - s1 * s5 * s6,
                c1 * c4 * s5 - s1 * c5,
                c1 * c4 * s5 * D6 - s1 * c5 * D6 - s1 * d3,
            ],
            [
                s1 * c4 * c5 * c6 - s1 * s4 * s6 - c1 * s5 * c6,
                -s1 * c4 * c5 * s6 - s1 * s4 * c6 + c1 * s5 * s6,
                s1 * c4 * s5 + c1 * c5,
                s1 * c4 * s5 * D6 + c1 * c5 * D6 + c1 * d3,
            ],
            [
                -s4 * c5 * c6 - c4 * s6,
                s4 * c5 * s6 - c4 * c6,
                -s4 * s5,
                -s4 * s5 * D6 + CYL_D1 + d2,
            ],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let reach = CYL_D1 + CYL_D2.1 + CYL_D3.1 + D6;
        let got = robot.fk_unchecked(&q).matrix();
        assert_close(&got, &want, reach, "cylindrical_wrist_6dof ^0T_6", &q);
        // Same pose as the two sub-chains composed: ^0T_3 (cylindrical) * ^3T_6 (wrist).
        let t03 = [
            [c1, 0.0, -s1, -d3 * s1],
            [s1, 0.0, c1, d3 * c1],
            [0.0, -1.0, 0.0, CYL_D1 + d2],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let composed = from_na(&(to_na(&t03) * to_na(&wrist_3t6(q[3], q[4], q[5], D6))));
        assert_close(&got, &composed, reach, "cylindrical_wrist_6dof 0T3*3T6", &q);
    }
}

// ---------------------------------------------------------------------------
// Lecture 19 (003): SCARA R-R-P-R with alpha2 = 180. robots/scara_4dof.json:
// a1 = 0.35, a2 = 0.25, d1 = 0.4, d4 = 0.05 m, d3 in [0, 0.2] m.

#[test]
fn scara_4dof_matches_corrected_closed_form() {
    const A1: f64 = 0.35;
    const A2: f64 = 0.25;
    const D1: f64 = 0.4;
    const D4: f64 = 0.05;
    let robot = load("scara_4dof");
    for q in configs(&[REV, REV, (0.0, 0.2), REV], 0x5CA4) {
        let (s1, c1) = sc(q[0]);
        let (s12, c12) = sc(q[0] + q[1]);
        let (s4, c4) = sc(q[3]);
        let d3 = q[2];
        // Height: z = d1 - d3 - d4 as in the notes (alpha2 = 180 turns z2, z3, z4
        // down, so positive d3 and d4 lower the tool); approach vector (0, 0, -1).
        // Slip corrected: the printed ^0T_4 has r22 = -s12 s4 + c12 c4; the
        // product ^0A_1 ^1A_2 ^2A_3 ^3A_4 gives r22 = -s12 s4 - c12 c4
        // (= -cos(theta1 + theta2 - theta4); with the printed sign the rotation
        // would not even be orthonormal). Found by evaluating the printed matrix
        // against the product of link matrices at random configurations: only
        // r22 differed (by up to 2). The printed ^1A_2 is right.
        let want = [
            [
                c12 * c4 + s12 * s4,
                -c12 * s4 + s12 * c4,
                0.0,
                A1 * c1 + A2 * c12,
            ],
            [
                s12 * c4 - c12 * s4,
                -s12 * s4 - c12 * c4,
                0.0,
                A1 * s1 + A2 * s12,
            ],
            [0.0, 0.0, -1.0, D1 - d3 - D4],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let got = robot.fk_unchecked(&q).matrix();
        assert_close(&got, &want, A1 + A2 + D1 + 0.2 + D4, "scara_4dof ^0T_4", &q);
        assert!(
            (got[2][3] - (D1 - d3 - D4)).abs() <= TOL,
            "scara z != d1 - d3 - d4 at q = {q:?}"
        );
        for (i, a) in [0.0, 0.0, -1.0].into_iter().enumerate() {
            assert!(
                (got[i][2] - a).abs() <= TOL,
                "scara approach != (0, 0, -1) at q = {q:?}"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Lecture 11 (004): articulated R⊥R∥R arm in modified DH. robots/articulated_rrr_mdh.json:
// d1 = 0.3, a2 = 0.4, a3 = 0.35 m; alpha1 = 270 deg.

const MDH_D1: f64 = 0.3;
const MDH_A2: f64 = 0.4;
const MDH_A3: f64 = 0.35;

#[test]
fn articulated_rrr_mdh_home_position() {
    let robot = load("articulated_rrr_mdh");
    // The lecture's home check: theta1 = theta2 = theta3 = 0 gives
    // [[1,0,0,a2+a3],[0,0,1,0],[0,-1,0,d1]].
    let want = [
        [1.0, 0.0, 0.0, MDH_A2 + MDH_A3],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0, MDH_D1],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let q = [0.0; 3];
    let reach = MDH_D1 + MDH_A2 + MDH_A3;
    assert_close(
        &robot.fk_unchecked(&q).matrix(),
        &want,
        reach,
        "articulated_rrr_mdh home",
        &q,
    );
}

#[test]
fn articulated_rrr_mdh_matches_lecture_closed_form() {
    let robot = load("articulated_rrr_mdh");
    for q in configs(&[REV; 3], 0x4D4) {
        let (s1, c1) = sc(q[0]);
        let (s2, c2) = sc(q[1]);
        let (s23, c23) = sc(q[1] + q[2]);
        // ^0T_4 as printed in lecture 11 (matches the product of the modified
        // link matrices). Slips elsewhere in that lecture, not used here: the
        // first slide of the general modified arm matrix has +d_i sin(alpha_{i-1})
        // in row 2 (the product Rx Tx Rz Tz, and the lecture's second copy, give
        // -d_i sin(alpha_{i-1})); one table header reads theta_{i-1} for theta_i.
        let r = MDH_A2 * c2 + MDH_A3 * c23;
        let want = [
            [c1 * c23, -c1 * s23, -s1, c1 * r],
            [s1 * c23, -s1 * s23, c1, s1 * r],
            [-s23, -c23, 0.0, MDH_D1 - MDH_A2 * s2 - MDH_A3 * s23],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let reach = MDH_D1 + MDH_A2 + MDH_A3;
        assert_close(
            &robot.fk_unchecked(&q).matrix(),
            &want,
            reach,
            "articulated_rrr_mdh ^0T_4",
            &q,
        );
    }
}

// ---------------------------------------------------------------------------
// General link matrices of the notes against `link_transform`.

/// Random DH parameters and joint values: a, alpha, d, theta, q.
fn link_params(rng: &mut Lcg) -> (f64, f64, f64, f64, f64) {
    (
        rng.uniform(0.0, 2.0),
        rng.uniform(-PI, PI),
        rng.uniform(-2.0, 2.0),
        rng.uniform(-PI, PI),
        rng.uniform(-PI, PI),
    )
}

#[test]
fn standard_link_matrix_matches_lecture_formula() {
    let mut rng = Lcg(0x57D);
    for _ in 0..N_CONFIGS {
        let (a, alpha, d, theta, q) = link_params(&mut rng);
        for kind in [JointKind::Revolute, JointKind::Prismatic, JointKind::Fixed] {
            let (th, dd) = match kind {
                JointKind::Revolute => (theta + q, d),
                JointKind::Prismatic => (theta, d + q),
                JointKind::Fixed => (theta, d),
            };
            let (st, ct) = sc(th);
            let (sa, ca) = sc(alpha);
            // ^{i-1}A_i of lectures 13, 18, 19 and 2.8.
            let want = [
                [ct, -ca * st, sa * st, a * ct],
                [st, ca * ct, -sa * ct, a * st],
                [0.0, sa, ca, dd],
                [0.0, 0.0, 0.0, 1.0],
            ];
            let got = link_transform(
                Convention::Standard,
                &DhRow {
                    kind,
                    a,
                    alpha,
                    d,
                    theta,
                },
                q,
            )
            .matrix();
            assert_close(
                &got,
                &want,
                4.0,
                "standard link matrix",
                &[a, alpha, d, theta, q],
            );
        }
    }
}

#[test]
fn modified_link_matrix_matches_lecture_formula() {
    let mut rng = Lcg(0x30D);
    for _ in 0..N_CONFIGS {
        let (a, alpha, d, theta, q) = link_params(&mut rng);
        for kind in [JointKind::Revolute, JointKind::Prismatic, JointKind::Fixed] {
            let (th, dd) = match kind {
                JointKind::Revolute => (theta + q, d),
                JointKind::Prismatic => (theta, d + q),
                JointKind::Fixed => (theta, d),
            };
            let (st, ct) = sc(th);
            let (sa, ca) = sc(alpha);
            // ^{i-1}T_i of lecture 11 (second copy; the first copy's +d sin(alpha)
            // in row 2 is a slip, see above).
            let want = [
                [ct, -st, 0.0, a],
                [st * ca, ct * ca, -sa, -dd * sa],
                [st * sa, ct * sa, ca, dd * ca],
                [0.0, 0.0, 0.0, 1.0],
            ];
            let got = link_transform(
                Convention::Modified,
                &DhRow {
                    kind,
                    a,
                    alpha,
                    d,
                    theta,
                },
                q,
            )
            .matrix();
            assert_close(
                &got,
                &want,
                4.0,
                "modified link matrix",
                &[a, alpha, d, theta, q],
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Lecture 2.8 (001): closed-form inverse of a link matrix, R^T and -R^T p.

#[test]
fn link_matrix_inverse_matches_closed_form_and_numeric_inverse() {
    let mut rng = Lcg(0x1417);
    for _ in 0..N_CONFIGS {
        let (a, alpha, d, theta, _) = link_params(&mut rng);
        let (st, ct) = sc(theta);
        let (sa, ca) = sc(alpha);
        // Inverse link coordinate transformation T_k^{k-1} of lecture 2.8.
        // Slip corrected: the slide prints entry (3,3) as -C(alpha_k); R^T has
        // +C(alpha_k) there (the (3,3) entry of R is C(alpha_k), a diagonal
        // entry, unchanged by transposition). Found by comparing the printed
        // matrix with numpy's inverse of the link matrix: only (3,3) differed.
        let want = [
            [ct, st, 0.0, -a],
            [-ca * st, ca * ct, sa, -d * sa],
            [sa * st, -sa * ct, ca, -d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let row = DhRow {
            kind: JointKind::Fixed,
            a,
            alpha,
            d,
            theta,
        };
        let link = link_transform(Convention::Standard, &row, 0.0);
        let numeric = to_na(&link.matrix())
            .try_inverse()
            .expect("a link matrix is invertible");
        let ctx = [a, alpha, d, theta];
        assert_close(
            &from_na(&numeric),
            &want,
            4.0,
            "closed-form inverse vs numeric",
            &ctx,
        );
        assert_close(
            &link.inverse().matrix(),
            &want,
            4.0,
            "Transform::inverse of a link",
            &ctx,
        );
    }
}

/// R^T, -R^T p of a homogeneous matrix, written out.
fn closed_form_inverse(m: &M4) -> M4 {
    let mut out = [
        [0.0, 0.0, 0.0, 0.0],
        [0.0; 4],
        [0.0; 4],
        [0.0, 0.0, 0.0, 1.0],
    ];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = m[j][i];
        }
        out[i][3] = -(m[0][i] * m[0][3] + m[1][i] * m[1][3] + m[2][i] * m[2][3]);
    }
    out
}

#[test]
fn arm_matrix_inverse_matches_numeric_inverse_of_product() {
    // For every course robot: the FK product ^0T_n (a product of link matrices),
    // its inverse as R^T, -R^T p, nalgebra's numeric inverse, and the library's
    // Transform::inverse all agree, and T * T^-1 = I.
    for (name, reach) in course_robots().iter().map(|c| (c.name, c.reach)) {
        let robot = load(name);
        let ranges: Vec<(f64, f64)> = robot
            .joints()
            .iter()
            .map(|j| match j.kind {
                JointKind::Prismatic => j.limits.expect("prismatic joints have limits"),
                _ => REV,
            })
            .collect();
        for q in configs(&ranges, 0x1B7 ^ name.len() as u64)
            .into_iter()
            .take(N_CONFIGS / 2)
        {
            let t: Transform = robot.fk_unchecked(&q);
            let m = t.matrix();
            let cf = closed_form_inverse(&m);
            let numeric = to_na(&m)
                .try_inverse()
                .expect("a rigid transform is invertible");
            let what = format!("{name} inverse");
            assert_close(&from_na(&numeric), &cf, reach, &what, &q);
            assert_close(&t.inverse().matrix(), &cf, reach, &what, &q);
            let ident = (t * t.inverse()).matrix();
            let eye = from_na(&Matrix4::identity());
            assert_close(&ident, &eye, reach, &format!("{name} T * T^-1"), &q);
        }
    }
}

// ---------------------------------------------------------------------------
// Joint counts of the course robot files.

struct CourseRobot {
    name: &'static str,
    /// DH rows (movable and fixed).
    rows: usize,
    /// Movable joints, R/P in table order.
    joints: &'static str,
    /// Arm size in the model's length unit, for tolerances.
    reach: f64,
}

fn course_robots() -> [CourseRobot; 9] {
    [
        CourseRobot {
            name: "planar_2dof",
            rows: 2,
            joints: "RR",
            reach: 0.7,
        },
        CourseRobot {
            name: "spatial_3r",
            rows: 3,
            joints: "RRR",
            reach: 1.0,
        },
        CourseRobot {
            name: "spherical_wrist",
            rows: 3,
            joints: "RRR",
            reach: 0.1,
        },
        CourseRobot {
            name: "inline_6dof",
            rows: 6,
            joints: "RRRRRR",
            reach: 1.15,
        },
        CourseRobot {
            name: "alpha_ii",
            rows: 5,
            joints: "RRRRR",
            reach: 700.1,
        },
        CourseRobot {
            name: "cylindrical_3dof",
            rows: 3,
            joints: "RPP",
            reach: 1.8,
        },
        CourseRobot {
            name: "cylindrical_wrist_6dof",
            rows: 6,
            joints: "RPPRRR",
            reach: 1.9,
        },
        CourseRobot {
            name: "scara_4dof",
            rows: 4,
            joints: "RRPR",
            reach: 1.25,
        },
        CourseRobot {
            name: "articulated_rrr_mdh",
            rows: 4,
            joints: "RRR",
            reach: 1.05,
        },
    ]
}

#[test]
fn course_robot_files_have_expected_joint_counts() {
    for c in course_robots() {
        let robot = load(c.name);
        assert_eq!(robot.name(), c.name, "name must equal the file stem");
        assert_eq!(robot.spec().links.len(), c.rows, "{}: DH rows", c.name);
        assert_eq!(robot.dof(), c.joints.len(), "{}: movable joints", c.name);
        let kinds: String = robot
            .joints()
            .iter()
            .map(|j| match j.kind {
                JointKind::Revolute => 'R',
                JointKind::Prismatic => 'P',
                JointKind::Fixed => 'F',
            })
            .collect();
        assert_eq!(kinds, c.joints, "{}: joint kinds in table order", c.name);
        for j in robot.joints() {
            if j.kind == JointKind::Prismatic {
                let (lo, hi) = j.limits.unwrap_or_else(|| {
                    panic!("{}: prismatic joint '{}' needs limits", c.name, j.name)
                });
                assert!(lo < hi, "{}: joint '{}' limits", c.name, j.name);
            }
        }
    }
}
