//! The evaluators of a compiled [`Program`] — single pose, single pose with every
//! frame, batch — and their instantiation per [`Kernel`] (`#[target_feature]`
//! copies of the same generic code, picked at run time).
//!
//! - Single pose: the joint angles of up to 8 joints and their sines and cosines
//!   are computed together as whole vectors ([`joint_values`]), then one
//!   [`step::apply`] per joint on a column-major 4×4 (each column one 4-wide
//!   vector).
//! - Frames: the same, emitting each DH row's frame from the state (precompiled
//!   [`FrameOffset`]s say how).
//! - Batch: blocks of 8 poses in structure-of-arrays form (every matrix entry an
//!   8-wide vector: one AVX-512 register), one dispatch per joint per block; in
//!   tiles of blocks whose joint values (read joint-major by one transpose per
//!   block, sines and cosines) are all computed before their steps.
//!
//! Depends on [`crate::program`], [`crate::step`], [`crate::sincos`],
//! [`crate::kernel`] and [`crate::batch_out`] (where batch poses go:
//! transforms or packed numbers). Unchecked by design, like the
//! [`crate::Chain`] methods.
#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays in step; they vectorise as written"
)]

use std::mem::MaybeUninit;

use crate::batch_out::BatchOut;
use crate::kernel::Kernel;
use crate::lane::{Arr, Lane, Lane8};
#[cfg(target_arch = "x86_64")]
use crate::lane::{Ymm, Ymm2, Zmm};
use crate::program::{CHUNK, Cols, FrameOffset, Lanes, Program, from_cols};
use crate::sincos::{madd, sincos_lanes, sincos_poly_lanes};
use crate::step::{self, State};
use crate::transform::Transform;

/// Poses per batch block.
pub(crate) const LANES: usize = 8;

/// `cos θ`, `sin θ`, `dz = d + q` (prismatic) and `q` of prismatic joints,
/// for one chunk of [`CHUNK`] joints of one pose.
struct JointValues {
    c: [f64; CHUNK],
    s: [f64; CHUNK],
    dz: [f64; CHUNK],
    qz: [f64; CHUNK],
}

/// How a kernel's function keeps a chunk's [`JointValues`] in its stack
/// frame (they stay there: the steps index them by joint): [`Natural`] or
/// [`Aligned64`].
trait Hold {
    fn hold(v: JointValues) -> Self;
    fn values(&self) -> &JointValues;
}

/// At the values' own alignment (8 bytes).
struct Natural(JointValues);

/// At 64 bytes, which makes the function realign its frame, and so its
/// vector spills. Measured on AMD Zen 4 (BENCHMARKS.md, 2026-12-07 evening):
/// unaligned, the AVX-512 single pose took ~30 or ~44 ns (PUMA) depending on
/// where the caller's stack lay (16 or 48 modulo 64: slow), so the same
/// binary ran at one speed or the other from process to process; the stalls
/// sat at the start of the joint-value computation, beside its spills of
/// 64-byte vectors (likely a store-to-load forward missed across a 32-byte
/// boundary). Aligned: ~30 in every process, and both batch functions
/// (AVX-512 and AVX2) faster too. The AVX2 single pose stays [`Natural`]:
/// realigned it took 40–45 ns in every process, where unaligned it takes 35
/// in most and 50 in some (not as a function of the stack address alone).
#[repr(align(64))]
struct Aligned64(JointValues);

impl Hold for Natural {
    #[inline(always)]
    fn hold(v: JointValues) -> Self {
        Natural(v)
    }
    #[inline(always)]
    fn values(&self) -> &JointValues {
        &self.0
    }
}

impl Hold for Aligned64 {
    #[inline(always)]
    fn hold(v: JointValues) -> Self {
        Aligned64(v)
    }
    #[inline(always)]
    fn values(&self) -> &JointValues {
        &self.0
    }
}

/// Joint values `q[start..start + CHUNK]` (missing ones count as 0) turned into
/// [`JointValues`], all lanes at once: `θ = q·scale + θ0` for revolute joints,
/// one vectorised sine/cosine, then revolute/prismatic picked by the 1/0 lane
/// masks (no branch).
#[inline(always)]
fn joint_values<const FMA: bool>(l: &Lanes, q: &[f64], start: usize, scale: f64) -> JointValues {
    let qb = load_chunk::<FMA>(q, start);
    let mut x = [0.0; CHUNK];
    for k in 0..CHUNK {
        x[k] = madd::<FMA>(qb[k], scale * l.rev[k], l.theta[k]);
    }
    let (sp, cp) = sincos_lanes::<FMA, CHUNK>(&x);
    let mut v = JointValues {
        c: [0.0; CHUNK],
        s: [0.0; CHUNK],
        dz: [0.0; CHUNK],
        qz: [0.0; CHUNK],
    };
    for k in 0..CHUNK {
        v.c[k] = madd::<FMA>(l.rev[k], cp[k], l.pri[k] * l.ct[k]);
        v.s[k] = madd::<FMA>(l.rev[k], sp[k], l.pri[k] * l.st[k]);
        v.qz[k] = qb[k] * l.pri[k];
        v.dz[k] = l.dz[k] + v.qz[k];
    }
    v
}

/// `q[start..start + CHUNK]`, zero past the end of `q`.
#[inline(always)]
fn load_chunk<const FMA: bool>(q: &[f64], start: usize) -> [f64; CHUNK] {
    #[cfg(target_arch = "x86_64")]
    if FMA {
        const { assert!(CHUNK == 8) };
        // SAFETY: `FMA = true` is only instantiated by the x86_64 kernels
        // (and the batch path's `redo`, which only they call), which run after
        // the CPU check for AVX2 and FMA.
        return unsafe { crate::lane::masked_load8(q, start) };
    }
    // Branch-free and call-free (a copy of the variable-length tail becomes a
    // `memcpy` call): clamped loads, then zero where past the end.
    let mut qb = [0.0; CHUNK];
    if let Some(last) = q.len().checked_sub(1) {
        for k in 0..CHUNK {
            let v = q[(start + k).min(last)];
            qb[k] = if start + k <= last { v } else { 0.0 };
        }
    }
    qb
}

/// A 4-lane column of the single-pose state: [`Lane`] plus loading and storing.
pub(crate) trait Col4: Lane {
    /// Loads four doubles.
    ///
    /// # Safety
    /// The CPU must support the target features the type's operations use
    /// (none for [`Arr`]; AVX2 and FMA for `Ymm`).
    unsafe fn load(a: &[f64; 4]) -> Self;
    /// The four doubles.
    fn store(self) -> [f64; 4];
    /// Writes the transform with columns `cols` to `out`.
    ///
    /// # Safety
    /// `out` must be valid for writes of one `Transform` (it may be uninitialised).
    #[inline(always)]
    unsafe fn store_transform(cols: &[Self; 4], out: *mut Transform) {
        let t = from_cols(&[
            cols[0].store(),
            cols[1].store(),
            cols[2].store(),
            cols[3].store(),
        ]);
        // SAFETY: by this function's contract.
        unsafe { out.write(t) };
    }
    /// The transform with columns `cols`, by value.
    #[inline(always)]
    fn to_transform(cols: &[Self; 4]) -> Transform {
        let mut t = MaybeUninit::<Transform>::uninit();
        // SAFETY: `t` is valid for writes and fully written by `store_transform`.
        unsafe {
            Self::store_transform(cols, t.as_mut_ptr());
            t.assume_init()
        }
    }
}

impl<const FMA: bool> Col4 for Arr<FMA, 4> {
    #[inline(always)]
    unsafe fn load(a: &[f64; 4]) -> Self {
        Arr(*a)
    }
    #[inline(always)]
    fn store(self) -> [f64; 4] {
        self.0
    }
}

#[cfg(target_arch = "x86_64")]
impl Col4 for Ymm {
    #[inline(always)]
    unsafe fn load(a: &[f64; 4]) -> Self {
        // SAFETY: forwarded from this function's own contract.
        unsafe { Ymm::load(a) }
    }
    #[inline(always)]
    fn store(self) -> [f64; 4] {
        Ymm::store(self)
    }
    #[inline(always)]
    unsafe fn store_transform(cols: &[Self; 4], out: *mut Transform) {
        // SAFETY: forwarded from this function's own contract.
        unsafe { Ymm::store_transform(cols, out) }
    }
    #[inline(always)]
    fn to_transform(cols: &[Self; 4]) -> Transform {
        Ymm::transform(cols)
    }
}

/// # Safety
/// See [`Col4::load`].
#[inline(always)]
unsafe fn load_cols<V: Col4>(c: &Cols) -> [V; 4] {
    // SAFETY: forwarded from this function's own contract.
    unsafe {
        [
            V::load(&c[0]),
            V::load(&c[1]),
            V::load(&c[2]),
            V::load(&c[3]),
        ]
    }
}

#[inline(always)]
fn transform_of<V: Col4>(m: &[V; 4]) -> Transform {
    V::to_transform(m)
}

/// World pose of the tool tip (see [`crate::Chain::forward`]).
///
/// # Safety
/// See [`Col4::load`].
#[inline(always)]
unsafe fn forward<const FMA: bool, V: Col4, H: Hold>(
    p: &Program,
    q: &[f64],
    scale: f64,
) -> Transform {
    // SAFETY: forwarded from this function's own contract.
    let mut m: State<V, 1> = [unsafe { load_cols::<V>(&p.base) }];
    for (ci, (lanes, steps)) in p.lanes.iter().zip(p.steps.chunks(CHUNK)).enumerate() {
        let held = H::hold(joint_values::<FMA>(lanes, q, ci * CHUNK, scale));
        let v = held.values();
        for (k, st) in steps.iter().enumerate().take(CHUNK) {
            step::apply::<V, 1>(
                st,
                &mut m,
                V::splat(v.c[k]),
                V::splat(v.s[k]),
                V::splat(v.dz[k]),
            );
        }
    }
    transform_of(&m[0])
}

/// `N = prev · Rz(θ) · Tz(qz)`: the state right after a joint, before its constant.
#[inline(always)]
fn joint_part<V: Lane>(prev: &[V; 4], c: f64, s: f64, qz: f64) -> [V; 4] {
    let [x, y, z, p] = *prev;
    let (c, s) = (V::splat(c), V::splat(s));
    [
        x.madd(c, y.mul(s)),
        x.nmadd(s, y.mul(c)),
        z,
        z.madd(V::splat(qz), p),
    ]
}

/// `n · k` for rigid transforms (`k` column-major).
#[inline(always)]
fn mul_cols<V: Lane>(n: &[V; 4], k: &Cols) -> [V; 4] {
    let mut out = *n;
    for j in 0..4 {
        let [a, b, c, _] = k[j];
        let last = if j == 3 { n[3] } else { V::splat(0.0) };
        out[j] = n[0].madd(
            V::splat(a),
            n[1].madd(V::splat(b), n[2].madd(V::splat(c), last)),
        );
    }
    out
}

/// `n` translated by `t` in its own axes.
#[inline(always)]
fn translate<V: Lane>(n: &[V; 4], t: &[f64; 3]) -> [V; 4] {
    let [a, b, c] = *t;
    let p = n[0].madd(
        V::splat(a),
        n[1].madd(V::splat(b), n[2].madd(V::splat(c), n[3])),
    );
    [n[0], n[1], n[2], p]
}

/// Where the frames path puts each frame.
pub(crate) trait FrameSink {
    /// Where the next frame goes: valid for writes of one `Transform`.
    fn next_slot(&mut self) -> *mut Transform;
    /// Called once after the last frame.
    fn finish(&mut self);
}

/// Frames handed to the callback at a time by [`Burst`].
const FRAME_BURST: usize = 16;

/// Collects frames and hands them to a callback in bursts, so the vector state
/// of the frames path is not live across the opaque calls (a call per frame
/// cost ~60 % more: spills around every call). Uninitialised, because
/// initialising 16 poses per evaluation costs more than it saves.
pub(crate) struct Burst<'a> {
    buf: [MaybeUninit<Transform>; FRAME_BURST],
    n: usize,
    frame: &'a mut dyn FnMut(&Transform),
}

impl<'a> Burst<'a> {
    pub(crate) fn new(frame: &'a mut dyn FnMut(&Transform)) -> Self {
        Burst {
            buf: [const { MaybeUninit::uninit() }; FRAME_BURST],
            n: 0,
            frame,
        }
    }

    #[inline(never)]
    fn flush(&mut self) {
        for f in &self.buf[..self.n] {
            // SAFETY: slots `0..n` were handed out by `next_slot` and written by the
            // frames path before the next call (its contract).
            (self.frame)(unsafe { f.assume_init_ref() });
        }
        self.n = 0;
    }
}

impl FrameSink for Burst<'_> {
    #[inline(always)]
    fn next_slot(&mut self) -> *mut Transform {
        if self.n == FRAME_BURST {
            self.flush();
        }
        self.n += 1;
        self.buf[self.n - 1].as_mut_ptr()
    }
    fn finish(&mut self) {
        self.flush();
    }
}

/// Writes frames into a slice, in order; frames beyond its end are dropped.
pub(crate) struct SliceSink<'a> {
    out: &'a mut [Transform],
    n: usize,
    spare: MaybeUninit<Transform>,
}

impl<'a> SliceSink<'a> {
    pub(crate) fn new(out: &'a mut [Transform]) -> Self {
        SliceSink {
            out,
            n: 0,
            spare: MaybeUninit::uninit(),
        }
    }
}

impl FrameSink for SliceSink<'_> {
    #[inline(always)]
    fn next_slot(&mut self) -> *mut Transform {
        let slot = match self.out.get_mut(self.n) {
            Some(t) => t as *mut Transform,
            None => self.spare.as_mut_ptr(),
        };
        self.n += 1;
        slot
    }
    fn finish(&mut self) {}
}

/// Tool pose, putting every frame into `sink` (see [`crate::Chain::forward_frames_into`]).
///
/// # Safety
/// See [`Col4::load`].
#[inline(always)]
unsafe fn forward_frames<const FMA: bool, V: Col4, S: FrameSink>(
    p: &Program,
    q: &[f64],
    scale: f64,
    sink: &mut S,
) -> Transform {
    for f in &p.lead_frames {
        // SAFETY: `next_slot` is valid for writes of one `Transform`.
        unsafe { sink.next_slot().write(*f) };
    }
    // SAFETY: forwarded from this function's own contract.
    let mut m: State<V, 1> = [unsafe { load_cols::<V>(&p.base) }];
    for (ci, (lanes, steps)) in p.lanes.iter().zip(p.steps.chunks(CHUNK)).enumerate() {
        let v = joint_values::<FMA>(lanes, q, ci * CHUNK, scale);
        for (k, st) in steps.iter().enumerate().take(CHUNK) {
            let j = ci * CHUNK + k;
            let offs = &p.frame_offsets[p.frame_start[j]..p.frame_start[j + 1]];
            let prev = m[0];
            step::apply::<V, 1>(
                st,
                &mut m,
                V::splat(v.c[k]),
                V::splat(v.s[k]),
                V::splat(v.dz[k]),
            );
            for off in offs {
                let t = match off {
                    FrameOffset::AfterStep => m[0],
                    FrameOffset::Translate(t) => {
                        translate(&joint_part(&prev, v.c[k], v.s[k], v.qz[k]), t)
                    }
                    FrameOffset::General(kc) => {
                        mul_cols(&joint_part(&prev, v.c[k], v.s[k], v.qz[k]), kc)
                    }
                };
                // SAFETY: `next_slot` is valid for writes of one `Transform`.
                unsafe { V::store_transform(&t, sink.next_slot()) };
            }
        }
    }
    sink.finish();
    transform_of(&m[0])
}

/// (Block, joint) pairs whose joint values a batch tile holds (see
/// [`forward_batch`]): 64 × 3 × 64 bytes, 12 KiB, in L1 with the tile's poses.
const TILE: usize = 64;

/// `cos θ`, `sin θ` and `dz` (prismatic joints only: a revolute joint's is its
/// constant `d`) of [`TILE`] (block, joint) pairs, eight poses each. Not
/// initialised up front (a small batch would pay for zeroing 12 KiB): each
/// entry is written by [`tile_joints`] before [`tile_steps`] reads it.
struct TileJoints {
    c: [MaybeUninit<[f64; LANES]>; TILE],
    s: [MaybeUninit<[f64; LANES]>; TILE],
    dz: [MaybeUninit<[f64; LANES]>; TILE],
}

impl TileJoints {
    fn new() -> Self {
        TileJoints {
            c: [const { MaybeUninit::uninit() }; TILE],
            s: [const { MaybeUninit::uninit() }; TILE],
            dz: [const { MaybeUninit::uninit() }; TILE],
        }
    }
}

/// Tool poses of many configurations (see [`crate::Chain::forward_batch`]).
///
/// In tiles of `TILE / dof` blocks of eight poses: first every joint value
/// of the tile (a block's configurations read joint-major by one transpose,
/// [`Lane8::load_joints`], then the sine and cosine polynomials, independent
/// of each other), then each block's chain of steps. A chain longer than
/// [`TILE`] joints goes one block at a time, [`TILE`] joints at a time.
/// Measured on an AMD EPYC (Zen 4) with AVX-512, against one block at a time
/// with a gather per joint: the transpose about a fifth less time per pose,
/// the revolute-only form ([`tile_joints`]) about 6 %, the tiles 2–3 %; the
/// AVX2 and portable kernels unchanged.
///
/// # Safety
/// See [`Lane8::load8`] and [`Col4::load`].
#[inline(always)]
unsafe fn forward_batch<const FMA: bool, V: Lane8, W: Col4, H: Hold, O: BatchOut + ?Sized>(
    p: &Program,
    q: &[f64],
    scale: f64,
    out: &mut O,
) {
    let dof = p.steps.len();
    if dof == 0 {
        // No joint: every (empty) configuration has the one constant pose.
        let pose = from_cols(&p.base);
        for i in 0..out.count() {
            out.put(i, &pose);
        }
        return;
    }
    let count = (q.len() / dof).min(out.count());
    let blocks = count / LANES;
    let per_tile = (TILE / dof).max(1);
    let mut tile = TileJoints::new();
    let mut b = 0;
    while b < blocks {
        let n = per_tile.min(blocks - b);
        let poses = b * LANES..(b + n) * LANES;
        let qt = &q[poses.start * dof..poses.end * dof];
        // SAFETY: forwarded from this function's own contract.
        if !unsafe { batch_tile::<FMA, V, O>(p, qt, scale, out, poses.start, &mut tile) } {
            // Rare: an angle beyond the polynomial's range; redo these poses one
            // by one (the single path falls back to `std` per joint).
            redo::<FMA, O>(p, q, scale, out, poses);
        }
        b += n;
    }
    for i in blocks * LANES..count {
        // SAFETY: forwarded from this function's own contract.
        let pose = unsafe { forward::<FMA, W, H>(p, &q[i * dof..(i + 1) * dof], scale) };
        out.put(i, &pose);
    }
}

/// Poses `range` of a batch by the single-pose path (compiled without the
/// kernel's target features: correct everywhere, and rare).
#[cold]
#[inline(never)]
fn redo<const FMA: bool, O: BatchOut + ?Sized>(
    p: &Program,
    q: &[f64],
    scale: f64,
    out: &mut O,
    range: std::ops::Range<usize>,
) {
    let dof = p.steps.len();
    for i in range {
        // SAFETY: `Arr` needs no target feature.
        let pose =
            unsafe { forward::<FMA, Arr<FMA, 4>, Natural>(p, &q[i * dof..(i + 1) * dof], scale) };
        out.put(i, &pose);
    }
}

/// The blocks of eight configurations in `q` (`q.len() / (8 · dof)` of them,
/// at most [`TILE`] joints in all unless there is one block) as poses
/// `first..` of `out`, in structure-of-arrays form: every entry of the 3×4
/// state is an 8-wide vector, so each step is whole-vector arithmetic,
/// dispatched once per joint per block. Returns false if an angle needs
/// `std` trigonometry (the poses are then wrong and the caller redoes them).
///
/// # Safety
/// See [`Lane8::load8`].
#[inline(always)]
unsafe fn batch_tile<const FMA: bool, V: Lane8, O: BatchOut + ?Sized>(
    p: &Program,
    q: &[f64],
    scale: f64,
    out: &mut O,
    first: usize,
    t: &mut TileJoints,
) -> bool {
    let dof = p.steps.len();
    let mut ok = true;
    if dof > TILE {
        // One block, its joints a window of `TILE` at a time.
        let mut m = base_state::<V>(p);
        for (w, steps) in p.steps.chunks(TILE).enumerate() {
            // SAFETY: forwarded from this function's own contract.
            ok &= unsafe { tile_joints::<FMA, V>(steps, q, dof, w * TILE, scale, t, 0) };
            // SAFETY: `tile_joints` has just written entries 0..steps.len();
            // the features are this function's contract.
            unsafe { tile_steps::<V>(steps, t, 0, &mut m) };
        }
        out.put8(first, &m);
        return ok;
    }
    let blocks = q.len() / (LANES * dof);
    for i in 0..blocks {
        let qb = &q[i * LANES * dof..(i + 1) * LANES * dof];
        // SAFETY: forwarded from this function's own contract.
        ok &= unsafe { tile_joints::<FMA, V>(&p.steps, qb, dof, 0, scale, t, i * dof) };
    }
    for i in 0..blocks {
        let mut m = base_state::<V>(p);
        // SAFETY: entries i·dof..(i + 1)·dof were written above (blocks · dof
        // ≤ TILE: the caller's tile size); the features are this function's contract.
        unsafe { tile_steps::<V>(&p.steps, t, i * dof, &mut m) };
        // One pose per lane, after the steps (which keep the vectors in registers).
        out.put8(first + i * LANES, &m);
    }
    ok
}

/// The base `B` as the batch state (every lane the same).
#[inline(always)]
fn base_state<V: Lane8>(p: &Program) -> State<V, 3> {
    let mut m: State<V, 3> = [[V::splat(0.0); 4]; 3];
    for r in 0..3 {
        for col in 0..4 {
            m[r][col] = V::splat(p.base[col][r]);
        }
    }
    m
}

/// Joints `j0..j0 + steps.len()` (`steps` their steps) of the eight
/// configurations of `dof` values in `qb` into tile entries `at..`; false if
/// an angle needs `std` trigonometry.
///
/// A revolute joint (every joint of most arms) writes only `c` and `s`, the
/// polynomial's own values (`rev · cos + pri · cos θ0` is `cos` again, in
/// value: a zero keeps its sign here); its `dz` is the constant `d`, which
/// [`tile_steps`] broadcasts. The two kinds are separate loops: with the
/// choice inside one, the compiler vectorised the polynomial in 128-bit
/// pieces (twice the time).
///
/// # Safety
/// See [`Lane8::load_joints`].
#[inline(always)]
#[allow(
    clippy::too_many_arguments,
    reason = "one inlined helper of batch_tile"
)]
unsafe fn tile_joints<const FMA: bool, V: Lane8>(
    steps: &[crate::program::Step],
    qb: &[f64],
    dof: usize,
    j0: usize,
    scale: f64,
    t: &mut TileJoints,
    at: usize,
) -> bool {
    let mut ok = true;
    for (g, group) in steps.chunks(LANES).enumerate() {
        // SAFETY: forwarded from this function's own contract.
        let qt = unsafe { V::load_joints(qb, dof, j0 + g * LANES) };
        for (jj, st) in group.iter().enumerate() {
            let e = at + g * LANES + jj;
            ok &= if st.is_revolute() {
                revolute_values::<FMA>(st, &qt[jj], scale, &mut t.c[e], &mut t.s[e])
            } else {
                joint_block_values::<FMA>(
                    st,
                    &qt[jj],
                    scale,
                    [&mut t.c[e], &mut t.s[e], &mut t.dz[e]],
                )
            };
        }
    }
    ok
}

/// A revolute joint's `cos θ`, `sin θ` for eight joint values `qv` (see
/// [`tile_joints`]); false if an angle needs `std` trigonometry.
#[inline(always)]
fn revolute_values<const FMA: bool>(
    st: &crate::program::Step,
    qv: &[f64; LANES],
    scale: f64,
    c: &mut MaybeUninit<[f64; LANES]>,
    s: &mut MaybeUninit<[f64; LANES]>,
) -> bool {
    let mut x = [0.0; LANES];
    for k in 0..LANES {
        // `scale · rev` is `scale` (rev = 1).
        x[k] = madd::<FMA>(qv[k], scale, st.theta);
    }
    let (sp, cp, bad) = sincos_poly_lanes::<FMA, LANES>(&x);
    c.write(cp);
    s.write(sp);
    !bad
}

/// Any joint's `cos θ`, `sin θ` and `dz` for eight joint values `qv`.
#[inline(always)]
fn joint_block_values<const FMA: bool>(
    st: &crate::program::Step,
    qv: &[f64; LANES],
    scale: f64,
    [c, s, dz]: [&mut MaybeUninit<[f64; LANES]>; 3],
) -> bool {
    let sc = scale * st.rev;
    let mut x = [0.0; LANES];
    for k in 0..LANES {
        x[k] = madd::<FMA>(qv[k], sc, st.theta);
    }
    let (sp, cp, bad) = sincos_poly_lanes::<FMA, LANES>(&x);
    let (mut cv, mut sv, mut dv) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
    for k in 0..LANES {
        cv[k] = madd::<FMA>(st.rev, cp[k], st.pri * st.ct);
        sv[k] = madd::<FMA>(st.rev, sp[k], st.pri * st.st);
        dv[k] = st.c[3][2] + qv[k] * st.pri;
    }
    c.write(cv);
    s.write(sv);
    dz.write(dv);
    !bad
}

/// The steps `steps` on the state `m`, their joint values tile entries `at..`.
///
/// # Safety
/// Entries `at..at + steps.len()` of `t` were written by [`tile_joints`] for
/// these steps (so `dz` for every prismatic one); see also [`Lane8::load8`].
#[inline(always)]
unsafe fn tile_steps<V: Lane8>(
    steps: &[crate::program::Step],
    t: &TileJoints,
    at: usize,
    m: &mut State<V, 3>,
) {
    for (jj, st) in steps.iter().enumerate() {
        let e = at + jj;
        // SAFETY: written (this function's contract); the features likewise.
        let (c, s, dz) = unsafe {
            let dz = if st.is_revolute() {
                V::splat(st.c[3][2])
            } else {
                V::load8(t.dz[e].assume_init_ref())
            };
            (
                V::load8(t.c[e].assume_init_ref()),
                V::load8(t.s[e].assume_init_ref()),
                dz,
            )
        };
        step::apply::<V, 3>(st, m, c, s, dz);
    }
}

/// One `#[target_feature]` copy of each evaluator per x86_64 kernel. There is no
/// AVX-512 copy of the frames path: it was ~20 % slower than the AVX2 copy
/// (measured on the project machine), and a frame is one 4-wide column set, so
/// AVX-512 has nothing to add; [`Kernel::Avx512`] runs the AVX2 copy. The two
/// [`Hold`] types are the single pose's and the batch's (see [`Aligned64`]).
macro_rules! instantiate {
    ($name:ident, $features:literal, $batch:ty, $hold:ty, $batch_hold:ty $(, $frames:ident)?) => {
        #[cfg(target_arch = "x86_64")]
        mod $name {
            use super::*;

            #[target_feature(enable = $features)]
            pub(super) fn forward(p: &Program, q: &[f64], scale: f64) -> Transform {
                // SAFETY: this function only runs on a CPU with the features above
                // (its callers check), which include what `Ymm` needs.
                unsafe { super::forward::<true, Ymm, $hold>(p, q, scale) }
            }

            $(
            #[target_feature(enable = $features)]
            pub(super) fn $frames(
                p: &Program,
                q: &[f64],
                scale: f64,
                sink: &mut Sink<'_>,
            ) -> Transform {
                // SAFETY: as in `forward`.
                unsafe {
                    match sink {
                        Sink::Burst(s) => super::forward_frames::<true, Ymm, _>(p, q, scale, s),
                        Sink::Slice(s) => super::forward_frames::<true, Ymm, _>(p, q, scale, s),
                    }
                }
            }
            )?

            #[target_feature(enable = $features)]
            pub(super) fn forward_batch<O: BatchOut + ?Sized>(
                p: &Program,
                q: &[f64],
                scale: f64,
                out: &mut O,
            ) {
                // SAFETY: as in `forward`.
                unsafe { super::forward_batch::<true, $batch, Ymm, $batch_hold, O>(p, q, scale, out) }
            }
        }
    };
}

instantiate!(avx2, "avx2,fma", Ymm2, Natural, Aligned64, forward_frames);
instantiate!(
    avx512,
    "avx512f,avx512vl,avx512dq,avx2,fma",
    Zmm,
    Aligned64,
    Aligned64
);

/// Single pose on `kernel`.
///
/// # Safety
/// The CPU must support `kernel` ([`Kernel::is_supported`]).
#[inline]
pub(crate) unsafe fn forward_on(kernel: Kernel, p: &Program, q: &[f64], scale: f64) -> Transform {
    match kernel {
        // SAFETY: `Arr` needs no target feature.
        Kernel::Portable => unsafe { forward::<false, Arr<false, 4>, Natural>(p, q, scale) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller guarantees the CPU supports Avx2Fma: avx2 and fma.
        Kernel::Avx2Fma => unsafe { avx2::forward(p, q, scale) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller guarantees the CPU supports Avx512: every feature enabled.
        Kernel::Avx512 => unsafe { avx512::forward(p, q, scale) },
        #[cfg(not(target_arch = "x86_64"))]
        // SAFETY: `Arr` needs no target feature.
        _ => unsafe { forward::<false, Arr<false, 4>, Natural>(p, q, scale) },
    }
}

/// Where the frames path puts the frames (one dispatch per evaluation).
#[allow(
    clippy::large_enum_variant,
    reason = "lives on the stack for one evaluation; boxing the burst buffer would allocate"
)]
pub(crate) enum Sink<'a> {
    /// To a callback, in bursts.
    Burst(Burst<'a>),
    /// Into a slice.
    Slice(SliceSink<'a>),
}

/// The portable frames path into `sink`.
fn frames_portable(p: &Program, q: &[f64], scale: f64, sink: &mut Sink<'_>) -> Transform {
    // SAFETY: `Arr` needs no target feature.
    unsafe {
        match sink {
            Sink::Burst(s) => forward_frames::<false, Arr<false, 4>, _>(p, q, scale, s),
            Sink::Slice(s) => forward_frames::<false, Arr<false, 4>, _>(p, q, scale, s),
        }
    }
}

/// Frames on `kernel`.
///
/// # Safety
/// The CPU must support `kernel` ([`Kernel::is_supported`]).
pub(crate) unsafe fn forward_frames_on(
    kernel: Kernel,
    p: &Program,
    q: &[f64],
    scale: f64,
    sink: &mut Sink<'_>,
) -> Transform {
    match kernel {
        Kernel::Portable => frames_portable(p, q, scale, sink),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller guarantees the CPU supports Avx2Fma or Avx512, so
        // avx2 and fma (Avx512 implies both; see `instantiate!` for why it runs this copy).
        Kernel::Avx2Fma | Kernel::Avx512 => unsafe { avx2::forward_frames(p, q, scale, sink) },
        #[cfg(not(target_arch = "x86_64"))]
        _ => frames_portable(p, q, scale, sink),
    }
}

/// Batch on `kernel`.
///
/// # Safety
/// The CPU must support `kernel` ([`Kernel::is_supported`]).
pub(crate) unsafe fn forward_batch_on<O: BatchOut + ?Sized>(
    kernel: Kernel,
    p: &Program,
    q: &[f64],
    scale: f64,
    out: &mut O,
) {
    match kernel {
        // SAFETY: `Arr` needs no target feature.
        Kernel::Portable => unsafe {
            forward_batch::<false, Arr<false, 8>, Arr<false, 4>, Natural, O>(p, q, scale, out)
        },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller guarantees the CPU supports Avx2Fma: avx2 and fma.
        Kernel::Avx2Fma => unsafe { avx2::forward_batch(p, q, scale, out) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller guarantees the CPU supports Avx512: every feature enabled.
        Kernel::Avx512 => unsafe { avx512::forward_batch(p, q, scale, out) },
        #[cfg(not(target_arch = "x86_64"))]
        // SAFETY: `Arr` needs no target feature.
        _ => unsafe {
            forward_batch::<false, Arr<false, 8>, Arr<false, 4>, Natural, O>(p, q, scale, out)
        },
    }
}
