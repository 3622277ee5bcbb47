// kinserve playground: a straight-line Cartesian path. "Plan path" asks
// POST /v1/robots/{name}/ik/path from the shown joints to the shown tool pose
// moved by the typed offset (orientation kept; position only for arms with
// fewer than six joints), draws the tool trace of the answer's `points` (their
// FK by POST …/fk/batch) as a polyline, and plays the arm through them; a path
// that stops short (fraction < 1) says at which step and why, and the part
// not taken is drawn dashed to the goal. Owns the "Cartesian path" controls
// and a layer of the 3D view; depends on api.js only, never on app.js (it is
// handed a `host`: {state, view, moveTo(values)}). Server strings reach the
// page through textContent only.

import { fkBatch, ikPath, problemText } from './api.js';

const $ = (id) => document.getElementById(id);
const FK_CHUNK = 1000; // configurations per FK batch request (the server takes up to 10,000)
const PLAY_MS = 2500; // a whole playback, about (each step 16–80 ms)

function positionOf(p) {
  if (p && Array.isArray(p.position)) return p.position.map(Number);
  if (p && Array.isArray(p.matrix)) return [0, 1, 2].map((k) => Number(p.matrix[k][3]));
  return null;
}

export class CartesianPath {
  constructor(host) {
    this.host = host;
    this.gen = 0;
    this.playGen = 0;
    this.name = null;
    this.points = []; // joints per step, start first (degrees / length unit)
    this.trace = []; // tool position per point
    this.goal = null; // the path's target position
    this.cursor = -1; // point shown by the playback
    this.layer = (b, view) => this.draw(b, view);
    $('path-plan').addEventListener('click', () => {
      this.plan().catch((err) => this.status(`Path failed: ${problemText(err)}`, 'error'));
    });
    $('path-play').addEventListener('click', () => this.play());
    $('path-clear').addEventListener('click', () => this.clear());
  }

  /** A new robot: offsets reset (10 cm down, in its length unit), nothing drawn. */
  setRobot(name, summary, model) {
    this.name = name;
    this.clear();
    const mm = model && model.length_unit === 'mm';
    $('path-unit').textContent = `(${mm ? 'mm' : 'm'})`;
    $('path-dx').value = '0';
    $('path-dy').value = '0';
    $('path-dz').value = mm ? '-100' : '-0.1';
  }

  status(text, kind) {
    const s = $('path-status');
    s.textContent = text;
    s.dataset.kind = kind || '';
  }

  clear() {
    this.gen++;
    this.playGen++;
    this.points = [];
    this.trace = [];
    this.goal = null;
    this.cursor = -1;
    this.status('');
    const d = $('path-status').dataset;
    for (const k of ['fraction', 'reason', 'points', 'played', 'request']) delete d[k];
    $('path-play').disabled = true;
    if (this.host.view) this.host.view.redraw();
  }

  /** The path from the shown joints to the shown tool pose plus the offset. */
  async plan() {
    const s = this.host.state;
    const pose = s.pose;
    if (!this.name) return;
    if (!pose || !Array.isArray(pose.position)) {
      this.status('Waiting for the tool pose…', 'busy');
      return;
    }
    const offset = ['path-dx', 'path-dy', 'path-dz'].map((id) => Number($(id).value));
    if (!offset.every(Number.isFinite)) {
      this.status('Type the offset as three numbers.', 'error');
      return;
    }
    this.clear();
    const gen = this.gen;
    const name = this.name;
    const position = pose.position.map((v, k) => Number(v) + offset[k]);
    const positionOnly = s.joints.length < 6 || !pose.quaternion;
    const q = pose.quaternion;
    const waypoint = positionOnly ? { position } : { position, quaternion: { w: q.w, x: q.x, y: q.y, z: q.z } };
    const body = { start: s.values.slice(), angle_unit: 'deg', waypoints: [waypoint] };
    if (positionOnly) body.position_only = true;
    const d = $('path-status').dataset;
    d.request = JSON.stringify(body);
    this.status('Planning…', 'busy');
    $('path-plan').disabled = true;
    try {
      const ans = await ikPath(name, body);
      if (gen !== this.gen) return;
      const points = Array.isArray(ans && ans.points) ? ans.points.filter(Array.isArray) : [];
      const trace = [];
      for (let i = 0; i < points.length; i += FK_CHUNK) {
        const fk = await fkBatch(name, points.slice(i, i + FK_CHUNK));
        if (gen !== this.gen) return;
        for (const p of (fk && fk.poses) || []) trace.push(positionOf(p));
      }
      this.points = points;
      this.trace = trace.filter(Boolean);
      this.goal = position;
      this.report(ans);
      if (points.length) this.play();
    } finally {
      $('path-plan').disabled = false;
    }
  }

  /** The status line: steps, fraction, and where and why the path stopped. */
  report(ans) {
    const d = $('path-status').dataset;
    const fraction = Number(ans.fraction);
    const steps = Math.max(0, this.points.length - 1);
    const stop = ans.stop && typeof ans.stop === 'object' ? ans.stop : null;
    d.fraction = String(fraction);
    d.points = String(this.points.length);
    d.reason = stop ? String(stop.reason) : '';
    if (!stop && fraction === 1) {
      this.status(`Complete: ${steps} step${steps === 1 ? '' : 's'} (fraction 1), played on the arm (Play replays it).`, 'ok');
      return;
    }
    const where = stop ? `at step ${stop.step} (waypoint ${stop.waypoint})` : 'early';
    const why = stop ? `${stop.reason}${stop.detail ? ` — ${stop.detail}` : ''}` : 'no reason given';
    this.status(`Stopped ${where}: ${why}. Fraction ${fraction}: the ${steps} step${steps === 1 ? '' : 's'} taken are drawn and played; the rest is dashed.`, 'warn');
  }

  /** Moves the arm through the points, start to end. */
  play() {
    const pts = this.points;
    if (!pts.length) return;
    const gen = ++this.playGen;
    const d = $('path-status').dataset;
    d.played = 'playing';
    $('path-play').disabled = false;
    const dt = Math.min(80, Math.max(16, PLAY_MS / pts.length));
    let i = 0;
    const tick = () => {
      if (gen !== this.playGen) return;
      this.cursor = i;
      this.host.moveTo(pts[i]);
      if (this.host.view) this.host.view.redraw();
      i += 1;
      if (i < pts.length) setTimeout(tick, dt);
      else d.played = 'done';
    };
    tick();
  }

  /** The view layer: the tool trace, its ends, the playback cursor, the rest dashed to the goal. */
  draw(b, view) {
    const d = view.canvas.dataset;
    if (!this.trace.length) {
      delete d.pathPoints;
      return;
    }
    const ctx = view.ctx;
    const line = (pts, color, width, dash) => {
      ctx.strokeStyle = color;
      ctx.lineWidth = width;
      ctx.setLineDash(dash || []);
      ctx.beginPath();
      for (let i = 0; i + 1 < pts.length; i++) {
        const s = view.segment(b, pts[i], pts[i + 1]);
        if (!s) continue;
        ctx.moveTo(s.a[0], s.a[1]);
        ctx.lineTo(s.b[0], s.b[1]);
      }
      ctx.stroke();
    };
    const dot = (p, color, r) => {
      const c = view.toCam(b, p);
      if (!view.ortho && c[2] < b.near) return;
      const s = view.toScreen(b, c);
      ctx.fillStyle = color;
      ctx.beginPath();
      ctx.arc(s[0], s[1], r, 0, Math.PI * 2);
      ctx.fill();
    };
    ctx.save();
    ctx.lineCap = 'round';
    const end = this.trace[this.trace.length - 1];
    if (this.goal && Math.hypot(...this.goal.map((v, k) => v - end[k])) > view.size * 1e-4) {
      line([end, this.goal], 'rgba(200, 60, 40, 0.7)', 2, [5, 4]);
      dot(this.goal, 'rgba(200, 60, 40, 0.9)', 4);
    }
    line(this.trace, '#e07b00', 3);
    dot(this.trace[0], '#e07b00', 4);
    dot(end, '#e07b00', 4);
    if (this.cursor >= 0 && this.trace[this.cursor]) dot(this.trace[this.cursor], '#7a3f00', 5);
    ctx.restore();
    d.pathPoints = String(this.trace.length);
  }
}
