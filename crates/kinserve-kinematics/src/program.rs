//! A chain compiled once, at registration, into the form the evaluators run:
//!
//! ```text
//! base · A_1 ⋯ A_n · tool  =  B · J_1 · C_1 · J_2 · C_2 ⋯ J_m · C_m
//! ```
//!
//! where `J_j = Rz(θ_j) · Tz(q_j)` is the only part of movable row `j` that
//! depends on its joint value (θ_j = θ0 + q for a revolute joint; the constant θ
//! and `Tz(q)` for a prismatic one) and every constant in between — the rest of
//! the DH rows (in either convention), the fixed rows, the base and the tool — is
//! folded into `B` and the `C_j`. Both conventions become the same program.
//!
//! Each `C_j` is then classified once ([`Step::kind`]): when its rotation is
//! `Rx(0°)`, `Rx(±90°)` or `Rx(180°)` and its translation is `(a, 0, d)` — every
//! real arm's table — the step is an *aligned* one whose arithmetic is a
//! rotation of two columns plus the non-zero translation terms (the column
//! relabelling is free); anything else is a *general* step. The evaluators
//! dispatch on the precompiled kind once per step ([`crate::step`]).
//!
//! Twists and constant angles within 1e-15 of a multiple of 90° are taken as
//! exactly that multiple (their sine or cosine exactly 0 and ±1): `π/2` in f64
//! has a cosine of 6.1e-17, not 0. The change is below 1e-15 × the reach.
//!
//! Owns nothing public. Depends on [`crate::transform`] and the row types of
//! [`crate::dh`] only.

use crate::dh::{Convention, DhRow, JointKind};
use crate::transform::Transform;

/// A rigid transform in column-major form: columns x, y, z of the rotation, then
/// the translation p; each column is `[row0, row1, row2, 0]` so it fills a
/// 4-wide vector.
pub(crate) type Cols = [[f64; 4]; 4];

/// Joints evaluated together by the polynomial sine/cosine (one 8-wide vector).
pub(crate) const CHUNK: usize = 8;

/// Step kind code for a general constant (full 3×4 product).
pub(crate) const GENERAL: u8 = 16;

/// What the rotation of an aligned constant is (`Rx` of 0°, +90°, −90°, 180°).
pub(crate) const ROT_0: u8 = 0;
/// `Rx(+90°)`.
pub(crate) const ROT_P90: u8 = 1;
/// `Rx(−90°)`.
pub(crate) const ROT_M90: u8 = 2;
/// `Rx(180°)`.
pub(crate) const ROT_180: u8 = 3;

/// One movable joint and the constant that follows it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step {
    /// `4·rot + 2·(a ≠ 0) + (d ≠ 0)` for an aligned constant (see the module
    /// docs), [`GENERAL`] otherwise. For a prismatic joint the `d` bit is always
    /// set, since `d` then carries the joint value.
    pub kind: u8,
    /// 1.0 for a revolute joint, 0.0 for a prismatic one.
    pub rev: f64,
    /// 0.0 for a revolute joint, 1.0 for a prismatic one.
    pub pri: f64,
    /// Zero offset θ0 (rad) of a revolute joint; 0 for a prismatic one.
    pub theta: f64,
    /// cos θ, sin θ of a prismatic joint's constant θ (0, 0 for a revolute one).
    pub ct: f64,
    /// See `ct`.
    pub st: f64,
    /// `C_j`, column-major. For an aligned step only `a = c[3][0]` and
    /// `d = c[3][2]` are read.
    pub c: Cols,
}

impl Step {
    /// Whether the joint is revolute (`pri` is 0, `rev` 1).
    #[inline(always)]
    pub(crate) fn is_revolute(&self) -> bool {
        self.pri == 0.0
    }
}

/// Per-lane copies of the step constants for [`CHUNK`] joints, so the joint
/// angles, sines and cosines of one pose are computed as whole vectors.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lanes {
    /// See [`Step::rev`] (0 in unused lanes).
    pub rev: [f64; CHUNK],
    /// See [`Step::pri`].
    pub pri: [f64; CHUNK],
    /// See [`Step::theta`].
    pub theta: [f64; CHUNK],
    /// See [`Step::ct`] (1 in unused lanes).
    pub ct: [f64; CHUNK],
    /// See [`Step::st`].
    pub st: [f64; CHUNK],
    /// The z translation of `C_j` (`d`), to which a prismatic joint value is added.
    pub dz: [f64; CHUNK],
}

/// Where a frame of [`crate::Chain::forward_frames_into`] comes from, relative to
/// `N_j = (state before joint j) · J_j`.
#[derive(Clone, Copy, Debug)]
pub(crate) enum FrameOffset {
    /// The frame is the state after the step (`C_j` is the row's own rest).
    AfterStep,
    /// `N_j` translated by `(x, y, z)` in its own axes (no rotation).
    Translate([f64; 3]),
    /// `N_j · K` for a general constant `K` (column-major).
    General(Cols),
}

/// The compiled chain.
#[derive(Clone, Debug)]
pub(crate) struct Program {
    /// `B`: base and every constant before the first joint (column-major).
    pub base: Cols,
    /// One per movable joint, in order.
    pub steps: Vec<Step>,
    /// `steps` in chunks of [`CHUNK`], lane by lane.
    pub lanes: Vec<Lanes>,
    /// The frames that do not depend on q: the base frame and those of fixed rows
    /// before the first joint.
    pub lead_frames: Vec<Transform>,
    /// Per joint, the frames of its own row and of the fixed rows after it,
    /// back to back: joint `j` has `frame_offsets[frame_start[j]..frame_start[j + 1]]`.
    pub frame_offsets: Vec<FrameOffset>,
    /// See `frame_offsets` (one more entry than joints).
    pub frame_start: Vec<usize>,
}

/// Sine and cosine of a constant angle (rad), snapped to exactly 0 / ±1 within
/// 1e-15 (see the module docs).
pub(crate) fn exact_sin_cos(angle: f64) -> (f64, f64) {
    const SNAP: f64 = 1e-15;
    let (s, c) = angle.sin_cos();
    if s.abs() <= SNAP {
        (0.0, c.signum())
    } else if c.abs() <= SNAP {
        (s.signum(), 0.0)
    } else {
        (s, c)
    }
}

fn rot_x(angle: f64) -> Transform {
    let (s, c) = exact_sin_cos(angle);
    Transform {
        rotation: [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        translation: [0.0; 3],
    }
}

fn rot_z(angle: f64) -> Transform {
    let (s, c) = exact_sin_cos(angle);
    Transform {
        rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    }
}

/// The constants before and after the joint part `J` of a row:
/// standard `A = Rz(θ)·Tz(d)·Tx(a)·Rx(α)` gives `pre = I`, `post = Tz(d)·Tx(a)·Rx(α)`;
/// modified `A = Rx(α)·Tx(a)·Rz(θ)·Tz(d)` gives `pre = Rx(α)·Tx(a)`, `post = Tz(d)`.
/// (`Rz(θ)` and `Tz(q)` commute with `Tz(d)`, so `J = Rz(θ)·Tz(q)` sits in between.)
fn split_row(convention: Convention, row: &DhRow) -> (Transform, Transform) {
    let tz = Transform::translation(0.0, 0.0, row.d);
    let tx = Transform::translation(row.a, 0.0, 0.0);
    match convention {
        Convention::Standard => (Transform::IDENTITY, tz * tx * rot_x(row.alpha)),
        Convention::Modified => (rot_x(row.alpha) * tx, tz),
    }
}

/// Column-major copy of a transform (lane 3 is 0).
pub(crate) fn to_cols(t: &Transform) -> Cols {
    let r = &t.rotation;
    let p = &t.translation;
    [
        [r[0][0], r[1][0], r[2][0], 0.0],
        [r[0][1], r[1][1], r[2][1], 0.0],
        [r[0][2], r[1][2], r[2][2], 0.0],
        [p[0], p[1], p[2], 0.0],
    ]
}

/// The transform of a column-major copy.
#[inline(always)]
pub(crate) fn from_cols(c: &Cols) -> Transform {
    Transform {
        rotation: [
            [c[0][0], c[1][0], c[2][0]],
            [c[0][1], c[1][1], c[2][1]],
            [c[0][2], c[1][2], c[2][2]],
        ],
        translation: [c[3][0], c[3][1], c[3][2]],
    }
}

/// The step kind of constant `c` after a joint (see [`Step::kind`]).
fn classify(c: &Transform, prismatic: bool) -> u8 {
    let rot = [
        (ROT_0, 0.0, 1.0),
        (ROT_P90, 1.0, 0.0),
        (ROT_M90, -1.0, 0.0),
        (ROT_180, 0.0, -1.0),
    ]
    .into_iter()
    .find(|&(_, s, co)| {
        c.rotation == [[1.0, 0.0, 0.0], [0.0, co, -s], [0.0, s, co]] && c.translation[1] == 0.0
    });
    match rot {
        Some((r, _, _)) => {
            let a = c.translation[0] != 0.0;
            let d = c.translation[2] != 0.0 || prismatic;
            4 * r + 2 * u8::from(a) + u8::from(d)
        }
        None => GENERAL,
    }
}

/// How frame `k` (relative to `N_j`) is produced, given the step constant `c`.
fn frame_offset(k: &Transform, c: &Transform) -> FrameOffset {
    if k == c {
        FrameOffset::AfterStep
    } else if k.rotation == Transform::IDENTITY.rotation {
        FrameOffset::Translate(k.translation)
    } else {
        FrameOffset::General(to_cols(k))
    }
}

/// Compiles the rows, base (world ← frame 0) and tool (flange ← tool tip).
pub(crate) fn compile(
    convention: Convention,
    rows: &[DhRow],
    base: &Transform,
    tool: Option<&Transform>,
) -> Program {
    struct Pending {
        kind: JointKind,
        theta: f64,
        /// Frames of this row and of the fixed rows after it, relative to `N_j`.
        frames: Vec<Transform>,
    }
    let mut acc = *base; // the constant since the last joint (or the base)
    let mut b = None;
    let mut lead_frames = vec![*base];
    let mut joints: Vec<(Pending, Transform)> = Vec::new();
    let mut current: Option<Pending> = None;
    for row in rows {
        let (pre, post) = split_row(convention, row);
        match row.kind {
            JointKind::Fixed => {
                let link = pre * rot_z(row.theta) * post;
                acc = acc * link;
                match &mut current {
                    Some(p) => p.frames.push(acc),
                    None => lead_frames.push(acc),
                }
            }
            kind => {
                let c = acc * pre;
                match current.take() {
                    Some(p) => joints.push((p, c)),
                    None => b = Some(c),
                }
                current = Some(Pending {
                    kind,
                    theta: row.theta,
                    frames: vec![post],
                });
                acc = post;
            }
        }
    }
    let tail = match tool {
        Some(t) => acc * *t,
        None => acc,
    };
    match current.take() {
        Some(p) => joints.push((p, tail)),
        None => b = Some(tail),
    }
    let steps: Vec<Step> = joints
        .iter()
        .map(|(p, c)| make_step(p.kind, p.theta, c))
        .collect();
    let mut frame_offsets = Vec::new();
    let mut frame_start = vec![0];
    for (p, c) in &joints {
        frame_offsets.extend(p.frames.iter().map(|k| frame_offset(k, c)));
        frame_start.push(frame_offsets.len());
    }
    Program {
        base: to_cols(&b.unwrap_or(*base)),
        lanes: steps.chunks(CHUNK).map(lanes_of).collect(),
        steps,
        lead_frames,
        frame_offsets,
        frame_start,
    }
}

fn make_step(kind: JointKind, theta: f64, c: &Transform) -> Step {
    let prismatic = kind == JointKind::Prismatic;
    let (st, ct) = if prismatic {
        exact_sin_cos(theta)
    } else {
        (0.0, 0.0)
    };
    Step {
        kind: classify(c, prismatic),
        rev: if prismatic { 0.0 } else { 1.0 },
        pri: if prismatic { 1.0 } else { 0.0 },
        theta: if prismatic { 0.0 } else { theta },
        ct,
        st,
        c: to_cols(c),
    }
}

fn lanes_of(steps: &[Step]) -> Lanes {
    let mut l = Lanes {
        rev: [0.0; CHUNK],
        pri: [0.0; CHUNK],
        theta: [0.0; CHUNK],
        ct: [1.0; CHUNK],
        st: [0.0; CHUNK],
        dz: [0.0; CHUNK],
    };
    for (k, s) in steps.iter().enumerate() {
        l.rev[k] = s.rev;
        l.pri[k] = s.pri;
        l.theta[k] = s.theta;
        l.ct[k] = s.ct;
        l.st[k] = s.st;
        l.dz[k] = s.c[3][2];
    }
    l
}
