// kinserve playground: main module (plain ES, no third-party code); server strings reach the page only through textContent.

import { ApiError, FkStream, fkBatch, getRobot, importUrdf, jacobianBatch, listRobots, putRobot } from './api.js';
import { jsonPathLines, lineForField } from './jsonlines.js';
import { showClosedForm } from './closedform.js';
import { SolutionGhosts } from './ghosts.js';
import { CartesianPath } from './path.js';
import { View3D, formatLen } from './view3d.js';

const DEFAULT_ROBOT = 'puma560';
const WORKSPACE_SAMPLES = 3000;
const WORKSPACE_BATCH = 1000; // server maximum is 10,000 per request
const RAD2DEG = 180 / Math.PI;
const DEG2RAD = Math.PI / 180; // the server's factor, in the same float

const $ = (id) => document.getElementById(id);

const state = {
  robots: [],
  name: null,
  model: null,
  joints: [], // movable joints: {row, kind, name, lo, hi, step, unit, defaulted}
  values: [],
  stream: null,
  gen: 0, // robot selection generation
  selection: null, // AbortController of the requests made for the selected robot
  wsGen: 0, // workspace run generation
  fkCount: 0,
  ikCount: 0,
  pose: null, // last tool pose shown
  target: null, // IK target position being dragged or nudged
  maxManip: 0, // largest manipulability seen for this robot
  manipRef: 0, // largest manipulability over a workspace sample (gauge scale)
  baseOrigin: [0, 0, 0],
  fieldErrors: [], // last register field errors (for re-locating markers on edit)
  syntaxError: null,
};

let view = null;
/** What the IK tool modules (ghosts.js, path.js) may use of the page. */
const host = {
  state,
  view: null,
  moveTo(values) {
    state.values = values.slice();
    setSliders(state.values);
    requestFk();
  },
};
let ikTools = [];

// ---------------------------------------------------------------- helpers --

function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (v === undefined || v === null) continue;
    if (k === 'class') e.className = v;
    else if (k === 'text') e.textContent = v;
    else if (k === 'dataset') Object.assign(e.dataset, v);
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (k in e && typeof v !== 'string') e[k] = v;
    else e.setAttribute(k, v);
  }
  for (const c of children) if (c !== null && c !== undefined) e.append(c);
  return e;
}

function clear(node) {
  while (node && node.firstChild) node.removeChild(node.firstChild);
}

function showGlobalError(msg) {
  const g = $('global-error');
  if (!g) return;
  g.textContent = msg || '';
  g.hidden = !msg;
}

function errText(err) {
  if (err instanceof ApiError) {
    const p = err.problem;
    return p.detail || p.title || `HTTP ${err.status}`;
  }
  return String(err && err.message ? err.message : err);
}

/** Rounded number text for tables (full precision stays in `#pos`). */
function fmt(x, digits = 6) {
  if (typeof x !== 'number' || !Number.isFinite(x)) return String(x);
  const s = x.toFixed(digits);
  return /^-0\.?0*$/.test(s) ? s.slice(1) : s;
}

const nice = formatLen;

/** Largest 1, 2, 5 × 10^k not above x. */
function niceStep(x) {
  if (!(x > 0) || !Number.isFinite(x)) return 0.001;
  const p = Math.pow(10, Math.floor(Math.log10(x)));
  const f = x / p;
  return (f >= 5 ? 5 : f >= 2 ? 2 : 1) * p;
}

/** A limit in rad turned into degrees that the server still finds inside the range. */
function radLimitToDeg(v, isLo) {
  let d = v * RAD2DEG;
  for (let i = 0; i < 64; i++) {
    const back = d * DEG2RAD;
    if (isLo ? back >= v : back <= v) return d;
    const ulp = Math.max(Math.abs(d) * Number.EPSILON, Number.MIN_VALUE);
    d = isLo ? d + ulp : d - ulp;
  }
  return d;
}

// ------------------------------------------------------------ robot list --

async function loadRobotList(preferred) {
  const robots = await listRobots();
  state.robots = robots;
  const sel = $('robot-select');
  clear(sel);
  for (const r of robots) {
    const name = String(r.name);
    const bits = [`${r.dof} DoF`, String(r.convention), String(r.length_unit)];
    if (r.source === 'registered') bits.push('registered');
    sel.append(el('option', { value: name, text: `${name} (${bits.join(', ')})` }));
  }
  const names = robots.map((r) => String(r.name));
  const pick = names.includes(preferred) ? preferred : names.includes(DEFAULT_ROBOT) ? DEFAULT_ROBOT : names[0];
  if (pick !== undefined) sel.value = pick;
  return pick;
}

/** The robot named by the page address (`/?robot=ur5e`), if any. */
function robotFromAddress() {
  return new URLSearchParams(location.search).get('robot');
}

/** Keeps `?robot=` in the address in step with the robot shown (no reload, no history entry). */
function showRobotInAddress(name) {
  const url = new URL(location.href);
  if (url.searchParams.get('robot') === name) return;
  url.searchParams.set('robot', name);
  history.replaceState(null, '', url);
}

async function start() {
  let delay = 500;
  for (;;) {
    try {
      const pick = await loadRobotList(robotFromAddress() || DEFAULT_ROBOT);
      showGlobalError('');
      if (pick === undefined) {
        showGlobalError('The server has no robots.');
        return;
      }
      await selectRobot(pick);
      return;
    } catch (err) {
      showGlobalError(`Could not load the robot list: ${errText(err)} (retrying…)`);
      await new Promise((r) => setTimeout(r, delay));
      delay = Math.min(delay * 2, 8000);
    }
  }
}

// ------------------------------------------------------------ robot model --

function movableJoints(model) {
  const angleRad = model.angle_unit === 'rad';
  const lenUnit = model.length_unit === 'mm' ? 'mm' : 'm';
  const out = [];
  (model.links || []).forEach((l, row) => {
    if (!l || l.joint === 'fixed') return;
    const prismatic = l.joint === 'prismatic';
    const lim = Array.isArray(l.limits) && l.limits.length === 2 ? l.limits.map(Number) : null;
    let lo;
    let hi;
    let defaulted = false;
    if (prismatic) {
      if (lim) [lo, hi] = lim;
      else {
        lo = 0;
        hi = lenUnit === 'mm' ? 1000 : 1;
        defaulted = true;
      }
    } else if (lim) {
      lo = angleRad ? radLimitToDeg(lim[0], true) : lim[0];
      hi = angleRad ? radLimitToDeg(lim[1], false) : lim[1];
    } else {
      lo = -180;
      hi = 180;
      defaulted = true;
    }
    const span = hi - lo;
    const step = prismatic ? niceStep(span / 1000) : span > 0 && span < 10 ? niceStep(span / 100) : 0.1;
    out.push({
      row,
      kind: prismatic ? 'prismatic' : 'revolute',
      name: typeof l.name === 'string' && l.name ? l.name : `joint${out.length + 1}`,
      lo,
      hi,
      step,
      unit: prismatic ? lenUnit : '°',
      defaulted,
    });
  });
  return out;
}

function homeValues() {
  return state.joints.map((j) => Math.min(Math.max(0, j.lo), j.hi));
}

function robotSize(model) {
  let s = 0;
  for (const l of model.links || []) {
    s += Math.abs(Number(l.a) || 0) + Math.abs(Number(l.d) || 0);
    if (l.joint === 'prismatic') {
      const lim = Array.isArray(l.limits) ? l.limits : [0, model.length_unit === 'mm' ? 1000 : 1];
      s += Math.max(Math.abs(Number(lim[0]) || 0), Math.abs(Number(lim[1]) || 0));
    }
  }
  const t = model.tool;
  if (t && Array.isArray(t.translation)) s += Math.hypot(...t.translation.map((v) => Number(v) || 0));
  if (t && Array.isArray(t.matrix)) s += Math.hypot(...[0, 1, 2].map((i) => Number(t.matrix[i] && t.matrix[i][3]) || 0));
  return s > 0 ? s : model.length_unit === 'mm' ? 1000 : 1;
}

function baseOriginOf(model) {
  const b = model.base;
  if (b && Array.isArray(b.matrix)) return [0, 1, 2].map((i) => Number(b.matrix[i] && b.matrix[i][3]) || 0);
  if (b && Array.isArray(b.translation)) return [0, 1, 2].map((i) => Number(b.translation[i]) || 0);
  return [0, 0, 0];
}

async function selectRobot(name) {
  const gen = ++state.gen;
  if (state.selection) state.selection.abort();
  state.selection = new AbortController();
  const { signal } = state.selection;
  state.wsGen++;
  if (state.stream) state.stream.close();
  state.stream = null;
  state.name = name;
  showRobotInAddress(name);
  setWsStatus('offline');
  setWorkspaceBusy(false);
  $('workspace-info').textContent = 'Samples random configurations within the joint limits and plots the tool positions.';
  delete $('workspace-info').dataset.count;
  delete $('workspace-info').dataset.maxReach;
  hideFkError();

  let model;
  try {
    model = await getRobot(name);
  } catch (err) {
    if (gen !== state.gen) return;
    showGlobalError(`Could not load robot '${name}': ${errText(err)}`);
    return;
  }
  if (gen !== state.gen) return;
  showGlobalError('');
  state.model = model;
  state.joints = movableJoints(model);
  state.values = homeValues();
  state.baseOrigin = baseOriginOf(model);

  renderSummary(model);
  renderDhTable(model);
  showClosedForm(name, () => gen === state.gen, signal);
  renderSliders();
  for (const t of ikTools) t.setRobot(name, state.robots.find((r) => String(r.name) === name), model);
  clearPose(model);
  prefillEditor(model);
  if (view) view.setRobot({ unit: model.length_unit === 'mm' ? 'mm' : 'm', size: robotSize(model), baseOrigin: state.baseOrigin });

  state.pose = null;
  state.target = null;
  state.maxManip = 0;
  state.manipRef = 0;
  delete $('manip').dataset.reference;
  loadManipReference(name, gen, signal);
  showIkStatus('');
  state.stream = new FkStream(name, {
    onReply: (msg, joints) => {
      if (gen !== state.gen) return;
      handleFkReply(msg, joints);
    },
    onIk: (msg, ik) => {
      if (gen !== state.gen) return;
      handleIkReply(msg, ik);
    },
    onGhost: (msg) => {
      if (gen !== state.gen || !view) return;
      if (msg && msg.pose) view.setGhost(Array.isArray(msg.frames) ? msg.frames : [], msg.pose);
    },
    onStatus: (s, detail) => {
      if (gen !== state.gen) return;
      setWsStatus(s, detail);
    },
  });
  requestFk();
}

function renderSummary(model) {
  const n = state.joints.length;
  const lu = model.length_unit === 'mm' ? 'mm' : 'm';
  $('robot-summary').textContent = `${model.name}: ${n} movable joint${n === 1 ? '' : 's'}, ${model.convention} DH, lengths in ${lu}; revolute sliders in degrees, prismatic in ${lu}.`;
  $('pos-unit').textContent = `(${lu})`;
  $('desc-text').textContent = typeof model.description === 'string' ? model.description : '(no description)';
  $('source-text').textContent = typeof model.source === 'string' ? `Source: ${model.source}` : '';
}

function renderDhTable(model) {
  const modified = model.convention === 'modified';
  const au = model.angle_unit === 'rad' ? 'rad' : 'deg';
  const lu = model.length_unit === 'mm' ? 'mm' : 'm';
  const rows = model.links || [];
  $('dh-meta').textContent =
    `Convention: ${modified ? 'modified (proximal, Craig): row i holds α(i−1), a(i−1), θ(i), d(i)' : 'standard (distal): A = Rz(θ)·Tz(d)·Tx(a)·Rx(α)'}` +
    ` · angles in ${au} · lengths in ${lu} · ${rows.length} rows, ${state.joints.length} movable.`;
  const thead = $('dh-table').tHead;
  const tbody = $('dh-table').tBodies[0];
  clear(thead);
  clear(tbody);
  const a = modified ? 'a(i−1)' : 'a';
  const alpha = modified ? 'α(i−1)' : 'α';
  thead.append(
    el(
      'tr',
      {},
      ...['#', 'name', 'joint', `${a} [${lu}]`, `${alpha} [${au}]`, `d [${lu}]`, `θ [${au}]`, 'limits', 'slider'].map((h) =>
        el('th', { scope: 'col', text: h }),
      ),
    ),
  );
  const jointByRow = new Map(state.joints.map((j, i) => [j.row, i]));
  rows.forEach((l, i) => {
    const ji = jointByRow.get(i);
    const j = ji === undefined ? null : state.joints[ji];
    let limits = '—';
    if (Array.isArray(l.limits)) {
      limits = `[${l.limits.map(String).join(', ')}] ${l.joint === 'prismatic' ? lu : au}`;
    } else if (j) {
      limits = j.kind === 'prismatic' ? `none (slider ${nice(j.lo)}…${nice(j.hi)} ${lu})` : 'none (slider ±180°)';
    }
    const variable = l.joint === 'revolute' ? 'θ' : l.joint === 'prismatic' ? 'd' : null;
    const cell = (key, text) => el('td', { class: variable === key ? 'var' : null, text, title: variable === key ? `joint value is added to ${key}` : null });
    tbody.append(
      el(
        'tr',
        { class: l.joint === 'fixed' ? 'fixed' : null },
        el('td', { text: String(i + 1) }),
        el('td', { text: typeof l.name === 'string' ? l.name : '' }),
        el('td', { text: String(l.joint) }),
        cell('a', String(l.a)),
        cell('alpha', String(l.alpha)),
        cell('d', String(l.d)),
        cell('θ', String(l.theta)),
        el('td', { text: limits }),
        el('td', { text: j ? `J${ji + 1}` : '—' }),
      ),
    );
  });
  const extra = [];
  if (model.base) extra.push(`base: ${JSON.stringify(model.base)}`);
  if (model.tool) extra.push(`tool: ${JSON.stringify(model.tool)}`);
  $('dh-extra').textContent = extra.length ? `${extra.join(' · ')} (${lu}, ${au})` : 'No base or tool transform (identity).';
}

// ---------------------------------------------------------------- sliders --

function renderSliders() {
  const box = $('joints');
  clear(box);
  state.joints.forEach((j, i) => {
    const id = `joint-${i}`;
    const unitText = j.kind === 'revolute' ? 'deg' : j.unit;
    const label = el('label', { for: id, text: `J${i + 1} ${j.name}` }, el('span', { class: 'unit', text: ` (${j.kind}, ${unitText})` }));
    const range = el('input', {
      type: 'range',
      id,
      min: String(j.lo),
      max: String(j.hi),
      step: String(j.step),
      'aria-valuetext': '',
    });
    const num = el('input', {
      type: 'number',
      id: `${id}-value`,
      min: String(j.lo),
      max: String(j.hi),
      step: 'any',
      inputmode: 'decimal',
      'aria-label': `J${i + 1} ${j.name} value in ${unitText}`,
    });
    const lim = el('span', { class: 'limits', text: `${nice(j.lo)} … ${nice(j.hi)} ${j.unit}${j.defaulted ? ' (default)' : ''}` });
    range.value = String(state.values[i]);
    num.value = String(state.values[i]);
    range.setAttribute('aria-valuetext', `${state.values[i]} ${unitText}`);
    const onRange = () => {
      let v = parseFloat(range.value);
      if (!Number.isFinite(v)) return;
      v = Math.min(Math.max(v, j.lo), j.hi);
      state.values[i] = v;
      num.value = String(v);
      range.setAttribute('aria-valuetext', `${v} ${unitText}`);
      requestFk();
    };
    range.addEventListener('input', onRange);
    range.addEventListener('change', onRange);
    const onNum = () => {
      const v = parseFloat(num.value);
      if (!Number.isFinite(v)) return;
      // Sent as typed (even outside the limits, so the server's error shows).
      state.values[i] = v;
      range.value = String(v);
      range.setAttribute('aria-valuetext', `${v} ${unitText}`);
      requestFk();
    };
    num.addEventListener('input', onNum);
    num.addEventListener('change', onNum);
    box.append(el('div', { class: 'joint', id: `${id}-row` }, label, el('div', { class: 'joint-inputs' }, range, num), lim));
  });
  if (!state.joints.length) box.append(el('p', { class: 'muted', text: 'This robot has no movable joints.' }));
}

function goHome() {
  state.values = homeValues();
  state.joints.forEach((j, i) => {
    const r = $(`joint-${i}`);
    const n = $(`joint-${i}-value`);
    if (r) {
      r.value = String(state.values[i]);
      r.setAttribute('aria-valuetext', `${state.values[i]} ${j.kind === 'revolute' ? 'deg' : j.unit}`);
    }
    if (n) n.value = String(state.values[i]);
  });
  requestFk();
}

function requestFk() {
  if (state.stream) state.stream.update(state.values);
}

/** Shows joint values on the sliders (without sending them). */
function setSliders(values) {
  state.joints.forEach((j, i) => {
    const r = $(`joint-${i}`);
    const n = $(`joint-${i}-value`);
    const v = values[i];
    if (r) {
      r.value = String(v);
      r.setAttribute('aria-valuetext', `${v} ${j.kind === 'revolute' ? 'deg' : j.unit}`);
    }
    if (n) n.value = String(v);
  });
}

// --------------------------------------------------------------------- IK --

/** IK of the tool to `position`, keeping the shown orientation, seeded with the shown joints. */
function solveIkTo(position) {
  const q = state.pose && state.pose.quaternion;
  if (!state.stream || !q || !position.every(Number.isFinite)) return;
  state.target = position.slice();
  document.body.dataset.dragTarget = JSON.stringify(position);
  if (view) view.setTarget(position);
  state.stream.solveIk({
    target: { position, quaternion: { w: q.w, x: q.x, y: q.y, z: q.z } },
    seed: state.values.slice(),
    angle_unit: 'deg',
    restarts: 10,
  });
}

function nudgeTool(delta) {
  const from = state.target || (state.pose && state.pose.position);
  if (!Array.isArray(from)) return;
  solveIkTo(from.map((v, k) => Number(v) + delta[k]));
}

function handleIkReply(msg, ik) {
  state.ikCount += 1;
  const d = document.body.dataset;
  d.ikCount = String(state.ikCount);
  d.ikTarget = JSON.stringify(ik && ik.target ? ik.target.position : null);
  if (msg && Array.isArray(msg.joints)) {
    d.ikResult = 'converged';
    d.ikJoints = JSON.stringify(msg.joints);
    showIkStatus('');
    if (view) view.setGhost(null);
    state.values = msg.joints.slice();
    setSliders(state.values);
    requestFk();
  } else if (msg && msg.error && msg.error.best_attempt) {
    d.ikResult = 'failed';
    const b = msg.error.best_attempt;
    showIkStatus(`IK failed: ${msg.error.detail || 'target not reached'} — best attempt drawn dashed.`, 'error');
    if (state.stream && Array.isArray(b.joints)) state.stream.ghost(b.joints);
  } else {
    d.ikResult = 'error';
    const e = (msg && msg.error) || {};
    showIkStatus(`IK error: ${e.detail || e.title || 'unexpected reply'}`, 'error');
  }
}

function showIkStatus(text, kind) {
  const s = $('ik-status');
  if (!s) return;
  s.textContent = text;
  s.dataset.kind = kind || '';
}

/**
 * The gauge's scale: the largest manipulability over 64 configurations drawn
 * within the joint limits (fixed seed), so a reading says how far the arm is
 * from its best, not from the best seen so far.
 */
async function loadManipReference(name, gen, signal) {
  let seed = 12345;
  const rand = () => {
    seed = (seed * 1103515245 + 12345) % 2147483648;
    return seed / 2147483648;
  };
  const configs = Array.from({ length: 64 }, () => state.joints.map((j) => j.lo + (j.hi - j.lo) * rand()));
  try {
    const out = await jacobianBatch(name, configs, signal);
    if (gen !== state.gen) return;
    const ms = (out.results || []).map((r) => Number(r.manipulability)).filter(Number.isFinite);
    state.manipRef = ms.length ? Math.max(...ms) : 0;
    $('manip').dataset.reference = String(state.manipRef);
  } catch (_) {
    // The largest reading so far stays the scale.
  }
}

/** The manipulability gauge and the singularity warning from an FK reply with the Jacobian. */
function showManipulability(msg) {
  const m = Number(msg.manipulability);
  if (!Number.isFinite(m)) return;
  state.maxManip = Math.max(state.maxManip, m);
  const meter = $('manip');
  const ref = Math.max(state.manipRef, state.maxManip);
  const c = msg.condition_number;
  $('manip-value').textContent = `${fmt(m, 4)} · condition ${c === null || c === undefined ? '∞' : fmt(Number(c), 4)}`;
  const near = msg.singular === true || c === null || Number(c) > 1e3;
  // Empty (red) at and near a singularity, whatever the scale.
  meter.value = near || !(ref > 0) ? 0 : Math.min(1, m / ref);
  $('singular-warning').hidden = !near;
  document.body.dataset.singular = String(!!msg.singular);
}

// --------------------------------------------------------------- FK reply --

function setWsStatus(s, detail) {
  const b = $('ws-status');
  const text = { connecting: 'connecting…', open: 'live', closed: 'reconnecting…', error: 'error', offline: 'offline' }[s] || s;
  b.textContent = text;
  b.dataset.state = s;
  b.title = detail ? String(detail) : `FK stream: ${text}`;
}

function handleFkReply(msg, joints) {
  if (msg && msg.error) {
    showFkError(msg.error);
    document.body.classList.add('fk-stale');
  } else if (msg && msg.pose) {
    hideFkError();
    document.body.classList.remove('fk-stale');
    showPose(msg.pose);
    state.pose = msg.pose;
    showManipulability(msg);
    const frames = Array.isArray(msg.frames) ? msg.frames : [];
    if (frames[0] && Array.isArray(frames[0].matrix)) {
      state.baseOrigin = [0, 1, 2].map((k) => Number(frames[0].matrix[k][3]) || 0);
    }
    if (view) view.setPose(frames, msg.pose);
  } else {
    showFkError({ title: 'Unexpected reply', detail: 'The FK stream reply has neither pose nor error.' });
  }
  document.body.dataset.lastJoints = JSON.stringify(joints || []);
  state.fkCount += 1;
  document.body.dataset.fkCount = String(state.fkCount);
}

function showPose(pose) {
  const m = Array.isArray(pose.matrix) ? pose.matrix : null;
  const p = Array.isArray(pose.position) ? pose.position : m ? [m[0][3], m[1][3], m[2][3]] : [];
  $('pos').textContent = p.map((v) => String(v)).join(', ');
  const q = pose.quaternion || {};
  $('quat').textContent = [q.w, q.x, q.y, q.z].map((v) => String(v)).join(', ');
  const rpy = Array.isArray(pose.rpy) ? pose.rpy : [];
  $('rpy').textContent = rpy.map((v) => String(v)).join(', ');
  $('rpy-deg').textContent = rpy.map((v) => fmt(Number(v) * RAD2DEG, 4)).join(', ');
  const tbody = $('matrix').tBodies[0];
  clear(tbody);
  if (m) {
    for (const row of m) {
      tbody.append(el('tr', {}, ...(Array.isArray(row) ? row : []).map((v) => el('td', { text: fmt(Number(v)), title: String(v) }))));
    }
  }
}

function clearPose(model) {
  for (const id of ['pos', 'quat', 'rpy', 'rpy-deg']) $(id).textContent = '';
  clear($('matrix').tBodies[0]);
  document.body.classList.remove('fk-stale');
  void model;
}

function showFkError(err) {
  const e = err && typeof err === 'object' ? err : {};
  const box = $('fk-error');
  $('fk-error-detail').textContent = `FK error${e.status ? ` (${e.status})` : ''}: ${e.detail || e.title || 'unknown error'}`;
  const list = $('fk-error-list');
  clear(list);
  document.querySelectorAll('.joint.invalid').forEach((n) => n.classList.remove('invalid'));
  const errors = Array.isArray(e.errors) ? e.errors : [];
  for (const fe of errors) {
    const field = fe && typeof fe.field === 'string' ? fe.field : '';
    const message = fe && fe.message !== undefined ? String(fe.message) : '';
    list.append(el('li', { text: field ? `${field}: ${message}` : message }));
    const m = /^joints\[(\d+)\]/.exec(field);
    if (m) {
      const row = $(`joint-${m[1]}-row`);
      if (row) row.classList.add('invalid');
    }
  }
  box.hidden = false;
}

function hideFkError() {
  $('fk-error').hidden = true;
  $('fk-error-detail').textContent = '';
  clear($('fk-error-list'));
  document.querySelectorAll('.joint.invalid').forEach((n) => n.classList.remove('invalid'));
}

// -------------------------------------------------------------- workspace --

function setWorkspaceBusy(busy) {
  $('workspace').disabled = !!busy;
  $('workspace').setAttribute('aria-busy', busy ? 'true' : 'false');
}

async function runWorkspace() {
  if (!state.name || !state.model) return;
  const gen = ++state.wsGen;
  const name = state.name;
  const joints = state.joints.slice();
  const info = $('workspace-info');
  const lu = state.model.length_unit === 'mm' ? 'mm' : 'm';
  setWorkspaceBusy(true);
  const configs = [];
  for (let k = 0; k < WORKSPACE_SAMPLES; k++) configs.push(joints.map((j) => j.lo + Math.random() * (j.hi - j.lo)));
  const points = [];
  try {
    for (let s = 0; s < configs.length; s += WORKSPACE_BATCH) {
      info.textContent = `Sampling… ${s} / ${configs.length} configurations`;
      const data = await fkBatch(name, configs.slice(s, s + WORKSPACE_BATCH));
      if (gen !== state.wsGen) return;
      const poses = data && Array.isArray(data.poses) ? data.poses : [];
      for (const p of poses) {
        const pos = p && Array.isArray(p.position) ? p.position : p && Array.isArray(p.matrix) ? [p.matrix[0][3], p.matrix[1][3], p.matrix[2][3]] : null;
        if (pos && pos.every((v) => Number.isFinite(Number(v)))) points.push(pos.map(Number));
      }
    }
  } catch (err) {
    if (gen !== state.wsGen) return;
    info.textContent = `Workspace sampling failed: ${errText(err)}`;
    if (err instanceof ApiError && err.problem.errors.length) {
      info.textContent += ` (${err.problem.errors.slice(0, 3).map((e) => `${e.field}: ${e.message}`).join('; ')})`;
    }
    setWorkspaceBusy(false);
    return;
  }
  if (gen !== state.wsGen) return;
  setWorkspaceBusy(false);
  if (!points.length) {
    info.textContent = 'The server returned no poses.';
    return;
  }
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  let reach = 0;
  const b = state.baseOrigin;
  for (const p of points) {
    for (let k = 0; k < 3; k++) {
      lo[k] = Math.min(lo[k], p[k]);
      hi[k] = Math.max(hi[k], p[k]);
    }
    reach = Math.max(reach, Math.hypot(p[0] - b[0], p[1] - b[1], p[2] - b[2]));
  }
  const r = (v) => nice(v);
  info.textContent =
    `${points.length} tool positions. Bounding box: x [${r(lo[0])}, ${r(hi[0])}], y [${r(lo[1])}, ${r(hi[1])}], z [${r(lo[2])}, ${r(hi[2])}] ${lu}. ` +
    `Maximum reach: ${r(reach)} ${lu} (from the base frame origin).`;
  info.dataset.count = String(points.length);
  info.dataset.maxReach = String(reach);
  info.dataset.bbox = JSON.stringify([lo, hi]);
  if (view) {
    view.setCloud(points);
    view.fit();
  }
}

function clearWorkspace() {
  state.wsGen++;
  setWorkspaceBusy(false);
  if (view) view.setCloud(null);
  const info = $('workspace-info');
  info.textContent = 'Workspace cleared.';
  delete info.dataset.count;
  delete info.dataset.maxReach;
  delete info.dataset.bbox;
}

// --------------------------------------------------------------- register --

const MODEL_KEYS = ['name', 'description', 'source', 'convention', 'angle_unit', 'length_unit', 'base', 'tool', 'links'];

function suggestName(name) {
  const base = String(name || 'robot');
  return `${base.slice(0, 59)}-copy`;
}

function prefillEditor(model) {
  const copy = {};
  for (const k of MODEL_KEYS) if (model[k] !== undefined) copy[k] = model[k];
  copy.name = suggestName(model.name);
  $('model-editor').value = JSON.stringify(copy, null, 2);
  clearRegisterErrors();
  $('register-status').textContent = '';
  $('register-status').className = '';
  renderGutter();
}

function clearRegisterErrors() {
  state.fieldErrors = [];
  state.syntaxError = null;
  clear($('field-errors'));
  clear($('editor-markers'));
  renderGutter();
}

function setRegisterStatus(text, kind) {
  const s = $('register-status');
  s.textContent = text;
  s.className = kind || '';
}

/** Line markers for the current field errors, found in the current editor text. */
function computeMarkers() {
  const text = $('model-editor').value;
  const markers = [];
  if (state.syntaxError) {
    markers.push({ line: state.syntaxError.line, message: state.syntaxError.message });
  }
  if (state.fieldErrors.length) {
    const located = jsonPathLines(text);
    for (const fe of state.fieldErrors) {
      const line = lineForField(fe.field, fe.message, located);
      if (line) markers.push({ line, message: fe.field ? `${fe.field}: ${fe.message}` : fe.message });
    }
  }
  return markers;
}

function renderMarkers() {
  const markers = computeMarkers();
  const list = $('editor-markers');
  clear(list);
  for (const m of markers) {
    list.append(
      el('li', {}, el('button', { type: 'button', class: 'linkish', text: `line ${m.line}: ${m.message}`, onclick: () => gotoLine(m.line) })),
    );
  }
  renderGutter(markers);
  return markers;
}

function renderGutter(markers) {
  const ed = $('model-editor');
  const gutter = $('editor-gutter');
  if (!ed || !gutter) return;
  const ms = markers || computeMarkers();
  const byLine = new Map();
  for (const m of ms) byLine.set(m.line, byLine.has(m.line) ? `${byLine.get(m.line)}\n${m.message}` : m.message);
  const n = Math.max(1, ed.value.split('\n').length);
  clear(gutter);
  const frag = document.createDocumentFragment();
  for (let i = 1; i <= n; i++) {
    const msg = byLine.get(i);
    frag.append(el('div', { class: msg ? 'marked' : null, title: msg || null, text: msg ? `● ${i}` : String(i) }));
  }
  gutter.append(frag);
  gutter.scrollTop = ed.scrollTop;
}

function scrollToLine(line) {
  const ed = $('model-editor');
  const lh = parseFloat(getComputedStyle(ed).lineHeight) || 19;
  ed.scrollTop = Math.max(0, (line - 1) * lh - ed.clientHeight / 3);
  $('editor-gutter').scrollTop = ed.scrollTop;
}

function gotoLine(line) {
  const ed = $('model-editor');
  const lines = ed.value.split('\n');
  let start = 0;
  for (let i = 0; i < line - 1 && i < lines.length; i++) start += lines[i].length + 1;
  const end = start + (lines[line - 1] || '').length;
  ed.focus();
  try {
    ed.setSelectionRange(start, end);
  } catch {
    /* ignore */
  }
  scrollToLine(line);
}

function showFieldErrors(errors) {
  const list = $('field-errors');
  clear(list);
  for (const fe of errors) {
    const li = el('li');
    if (fe.field) li.append(el('code', { text: fe.field }), document.createTextNode(`: ${fe.message}`));
    else li.textContent = fe.message;
    list.append(li);
  }
}

async function register() {
  const text = $('model-editor').value;
  const token = $('token').value.trim();
  clearRegisterErrors();
  let obj;
  try {
    obj = JSON.parse(text);
  } catch (err) {
    const located = jsonPathLines(text);
    const e = located.error || { message: String(err && err.message ? err.message : err), line: 1, column: 1 };
    state.syntaxError = { line: e.line, message: `JSON syntax error: ${e.message} (column ${e.column})` };
    setRegisterStatus(`The model is not valid JSON: ${e.message} at line ${e.line}, column ${e.column}.`, 'error');
    showFieldErrors([{ field: '', message: `line ${e.line}, column ${e.column}: ${e.message}` }]);
    renderMarkers();
    scrollToLine(e.line);
    return;
  }
  if (!obj || typeof obj !== 'object' || Array.isArray(obj) || typeof obj.name !== 'string' || !obj.name) {
    state.fieldErrors = [{ field: 'name', message: 'a robot name (string) is required; it decides the URL' }];
    setRegisterStatus('The model needs a "name".', 'error');
    showFieldErrors(state.fieldErrors);
    renderMarkers();
    return;
  }
  const name = obj.name;
  const btn = $('register');
  btn.disabled = true;
  setRegisterStatus(`Registering '${name}'…`, 'busy');
  try {
    const res = await putRobot(name, text, token);
    const verb = res.status === 201 ? 'Created' : 'Updated';
    setRegisterStatus(`${verb} robot '${name}' (HTTP ${res.status}).`, 'ok');
    try {
      await loadRobotList(state.name);
    } catch (err) {
      setRegisterStatus(`${verb} robot '${name}' (HTTP ${res.status}), but the robot list could not be refreshed: ${errText(err)}`, 'ok');
    }
  } catch (err) {
    if (err instanceof ApiError) {
      const p = err.problem;
      const head = p.detail || p.title || `HTTP ${err.status}`;
      setRegisterStatus(err.status ? `${head} (HTTP ${err.status})` : head, 'error');
      state.fieldErrors = p.errors;
      showFieldErrors(p.errors);
      const markers = renderMarkers();
      if (markers.length) scrollToLine(markers[0].line);
    } else {
      setRegisterStatus(`Registration failed: ${errText(err)}`, 'error');
    }
  } finally {
    btn.disabled = false;
  }
}

/** Imports the URDF in the text area as a robot and shows it. */
async function importFromUrdf() {
  const urdf = $('urdf-text').value;
  const name = $('urdf-name').value.trim();
  const status = (text, kind) => {
    $('import-status').textContent = text;
    $('import-status').dataset.kind = kind;
  };
  if (!name || !urdf.trim()) {
    status('Give the robot a name and paste (or pick) a URDF.', 'error');
    return;
  }
  const btn = $('import-urdf');
  btn.disabled = true;
  status(`Importing '${name}'…`, 'busy');
  try {
    const res = await importUrdf(name, urdf, {
      tipLink: $('urdf-tip').value.trim(),
      convention: $('urdf-convention').value,
      token: $('token').value.trim(),
    });
    status(`Imported '${name}' with ${(res.data && res.data.links || []).length} DH rows (HTTP ${res.status}).`, 'ok');
    if ((await loadRobotList(name)) === name) await selectRobot(name);
  } catch (err) {
    if (err instanceof ApiError) {
      const p = err.problem;
      const fields = (p.errors || []).map((e) => (e.field ? `${e.field}: ${e.message}` : e.message)).join('; ');
      status(`${p.detail || p.title || 'Import failed'}${fields && !String(p.detail).includes(fields) ? ` (${fields})` : ''} (HTTP ${err.status})`, 'error');
    } else {
      status(`Import failed: ${errText(err)}`, 'error');
    }
  } finally {
    btn.disabled = false;
  }
}

/** A picked URDF file fills the text area (and the name, when empty). */
async function pickUrdfFile(ev) {
  const file = ev.target.files && ev.target.files[0];
  if (!file) return;
  $('urdf-text').value = await file.text();
  if (!$('urdf-name').value.trim()) {
    $('urdf-name').value = file.name.replace(/\.[^.]*$/, '').toLowerCase().replace(/[^a-z0-9_-]+/g, '-').replace(/^-+/, '');
  }
}

// ------------------------------------------------------------------- init --

function init() {
  document.body.dataset.fkCount = '0';
  document.body.dataset.ikCount = '0';
  const canvas = $('view');
  try {
    view = new View3D(canvas);
    view.onToolDrag = solveIkTo;
    view.onToolNudge = nudgeTool;
    if (!view.available) {
      view = null;
      canvas.replaceWith(el('p', { id: 'view', class: 'muted', text: '3D view unavailable: this browser has no Canvas 2D context.' }));
    }
  } catch {
    view = null;
  }
  ikTools = [new SolutionGhosts(host), new CartesianPath(host)];
  host.view = view;
  if (view) {
    view.layers.push(...ikTools.map((t) => t.layer));
    view.onPick = (x, y) => ikTools[0].pick(x, y);
  }
  $('robot-select').addEventListener('change', (e) => selectRobot(e.target.value));
  $('home').addEventListener('click', goHome);
  $('fit').addEventListener('click', () => view && view.fit());
  $('ortho').addEventListener('change', (e) => view && view.setOrtho(e.target.checked));
  $('workspace').addEventListener('click', () => {
    runWorkspace().catch((err) => {
      $('workspace-info').textContent = `Workspace sampling failed: ${errText(err)}`;
      setWorkspaceBusy(false);
    });
  });
  $('workspace-clear').addEventListener('click', clearWorkspace);
  $('register').addEventListener('click', () => {
    register().catch((err) => setRegisterStatus(`Registration failed: ${errText(err)}`, 'error'));
  });
  $('reset-editor').addEventListener('click', () => state.model && prefillEditor(state.model));
  $('import-urdf').addEventListener('click', () => {
    importFromUrdf().catch((err) => {
      $('import-status').textContent = `Import failed: ${errText(err)}`;
    });
  });
  $('urdf-file').addEventListener('change', (ev) => {
    pickUrdfFile(ev).catch(() => {});
  });
  const ed = $('model-editor');
  let t = null;
  ed.addEventListener('input', () => {
    if (t) clearTimeout(t);
    t = setTimeout(() => {
      t = null;
      state.syntaxError = null; // stale once the text changed
      if (state.fieldErrors.length) renderMarkers();
      else {
        clear($('editor-markers'));
        renderGutter();
      }
    }, 150);
  });
  ed.addEventListener('scroll', () => {
    $('editor-gutter').scrollTop = ed.scrollTop;
  });
  start();
}

if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', init);
else init();
