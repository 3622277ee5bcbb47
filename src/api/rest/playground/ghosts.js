// kinserve playground: every closed-form IK solution as a ghost arm.
// "All solutions" asks POST /v1/robots/{name}/ik with `solutions: "all"` for
// the shown tool pose (seeded with the shown joints), fetches each solution's
// frames (POST …/fk with `frames`), draws them as thin translucent arms over the
// real one and lists them with their branch; clicking a ghost, its label or
// its list entry moves the arm there. Arms without a closed form (no
// `ik_class` in the robot list) get the control disabled, with the reason.
// Owns the "Every IK solution" controls and a layer of the 3D view; depends
// on api.js and view3d.js only, never on app.js (it is handed a `host`:
// {state, view, moveTo(values)}). Server strings reach the page through
// textContent only.

import { fkFrames, problemText, solveIk } from './api.js';
import { frameOf } from './view3d.js';

/** Solutions asked for (each is drawn, so each costs one FK request). */
export const MAX_GHOSTS = 32;

const $ = (id) => document.getElementById(id);
const dist = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);

/** Hue of group `g` (golden-angle steps: neighbours differ). */
const hue = (g) => Math.round((210 + g * 137.508) % 360);

/** Distance (px) from point p to the screen segment a–b. */
function segDistance(p, a, b) {
  const vx = b[0] - a[0];
  const vy = b[1] - a[1];
  const l2 = vx * vx + vy * vy;
  const t = l2 > 0 ? Math.min(1, Math.max(0, ((p[0] - a[0]) * vx + (p[1] - a[1]) * vy) / l2)) : 0;
  return Math.hypot(p[0] - a[0] - t * vx, p[1] - a[1] - t * vy);
}

/** A group's label: its first solution's number, and how many coincide there ("4 ×3"). */
function groupText(members) {
  return members.length > 1 ? `${members[0] + 1} ×${members.length}` : String(members[0] + 1);
}

function jointText(v) {
  const s = Number(v).toFixed(3);
  return /^-0\.0*$/.test(s) ? s.slice(1) : s;
}

export class SolutionGhosts {
  constructor(host) {
    this.host = host;
    this.gen = 0;
    this.name = null;
    this.enabled = false;
    this.ghosts = []; // [{joints, branch, singular, distance, frames, tool, group}]
    this.groups = []; // [[index, ...]]: ghosts drawn alike (2π copies)
    this.selected = -1;
    this.hits = []; // from the last draw: [{group, segs: [[a, b]...], label: {x, y, w} | null}]
    this.layer = (b, view) => this.draw(b, view);
    $('ik-all').addEventListener('click', () => {
      this.solve().catch((err) => this.status(`No solutions: ${problemText(err)}`, 'error'));
    });
    $('ik-all-clear').addEventListener('click', () => this.clear());
    $('ik-solutions').addEventListener('click', (e) => {
      const btn = e.target.closest('button[data-index]');
      if (btn) this.select(Number(btn.dataset.index));
    });
  }

  /** A new robot: the control is enabled only with a closed form (`summary.ik_class`). */
  setRobot(name, summary) {
    this.gen++;
    this.name = name;
    this.clear();
    const cls = summary && typeof summary.ik_class === 'string' && summary.ik_class ? summary.ik_class : null;
    this.enabled = !!cls;
    const btn = $('ik-all');
    btn.disabled = !cls;
    btn.dataset.available = String(!!cls);
    $('ik-all-reason').textContent = cls
      ? `Closed form: ${cls}. Solves the shown tool pose, nearest the shown joints first.`
      : `Not available for ${name}: it has no closed-form IK (no ik_class in the robot list), so the server cannot list every solution; dragging the tool still solves numerically, one answer at a time.`;
  }

  status(text, kind) {
    const s = $('ik-all-status');
    s.textContent = text;
    s.dataset.kind = kind || '';
  }

  clear() {
    this.gen++;
    this.ghosts = [];
    this.groups = [];
    this.selected = -1;
    this.hits = [];
    this.status('');
    const s = $('ik-all-status');
    delete s.dataset.count;
    delete s.dataset.selected;
    delete s.dataset.request;
    $('ik-solutions').replaceChildren();
    $('ik-all').disabled = !this.enabled;
    this.redraw();
  }

  redraw() {
    if (this.host.view) this.host.view.redraw();
  }

  /** Every solution of the shown tool pose, seeded with the shown joints. */
  async solve() {
    const s = this.host.state;
    const pose = s.pose;
    if (!this.enabled || !this.name) return;
    if (!pose || !Array.isArray(pose.position) || !pose.quaternion) {
      this.status('Waiting for the tool pose…', 'busy');
      return;
    }
    this.clear();
    const gen = this.gen;
    const name = this.name;
    const q = pose.quaternion;
    const body = {
      target: { position: pose.position.map(Number), quaternion: { w: q.w, x: q.x, y: q.y, z: q.z } },
      seed: s.values.slice(),
      angle_unit: 'deg',
      solutions: 'all',
      max_solutions: MAX_GHOSTS,
    };
    const st = $('ik-all-status');
    st.dataset.request = JSON.stringify(body);
    this.status('Solving…', 'busy');
    $('ik-all').disabled = true;
    try {
      const ans = await solveIk(name, body);
      if (gen !== this.gen) return;
      const sols = Array.isArray(ans && ans.solutions) ? ans.solutions : [];
      const fks = await Promise.all(sols.map((x) => fkFrames(name, x.joints)));
      if (gen !== this.gen) return;
      this.ghosts = sols.map((x, i) => this.ghostOf(x, fks[i]));
      this.groupGhosts();
      this.renderList();
      const n = this.ghosts.length;
      const more = ans.truncated ? `; more fit the limits than the ${MAX_GHOSTS} asked for` : '';
      this.status(`${n} solution${n === 1 ? '' : 's'} inside the joint limits (${ans.solver} solver)${more}, nearest the shown joints first; click a ghost or an entry to move the arm there.`, 'ok');
      st.dataset.count = String(n);
    } catch (err) {
      if (gen === this.gen) this.status(`No solutions: ${problemText(err)}`, 'error');
    } finally {
      if (gen === this.gen) $('ik-all').disabled = !this.enabled;
      this.redraw();
    }
  }

  ghostOf(sol, fk) {
    const frames = (Array.isArray(fk && fk.frames) ? fk.frames : []).map((p) => frameOf(p && p.matrix)).filter(Boolean);
    const tool = fk && fk.pose ? frameOf(fk.pose.matrix) : null;
    const size = this.host.view ? this.host.view.size : 1;
    const chain = frames.map((f) => f.o);
    if (tool && (!chain.length || dist(tool.o, chain[chain.length - 1]) > size * 1e-6)) chain.push(tool.o);
    // A stub along each joint's z axis tells wrist flips apart (their origins coincide).
    const stubs = frames.slice(0, -1).map((f) => [f.o, f.o.map((v, k) => v + f.z[k] * size * 0.1)]);
    return {
      joints: Array.isArray(sol.joints) ? sol.joints.map(Number) : [],
      branch: sol.branch || null,
      singular: Array.isArray(sol.singular) ? sol.singular.map(String) : [],
      distance: Number(sol.distance),
      chain,
      stubs,
      points: chain.concat(stubs.map((s) => s[1])),
      group: -1,
    };
  }

  /** Ghosts that would be drawn alike (2π copies) share a group. */
  groupGhosts() {
    const size = this.host.view ? this.host.view.size : 1;
    const same = (a, b) => a.points.length === b.points.length && a.points.every((p, k) => dist(p, b.points[k]) <= size * 1e-6);
    this.groups = [];
    this.ghosts.forEach((g, i) => {
      const found = this.groups.findIndex((members) => same(this.ghosts[members[0]], g));
      if (found >= 0) {
        this.groups[found].push(i);
        g.group = found;
      } else {
        g.group = this.groups.length;
        this.groups.push([i]);
      }
    });
    // Each group's label goes where it differs most from the other groups.
    this.labelAt = this.groups.map((members, g) => {
      const pts = this.ghosts[members[0]].points;
      let best = Math.floor((this.ghosts[members[0]].chain.length - 1) / 2);
      let bestD = -1;
      pts.forEach((p, k) => {
        let d = Infinity;
        this.groups.forEach((other, h) => {
          if (h !== g && this.ghosts[other[0]].points[k]) d = Math.min(d, dist(p, this.ghosts[other[0]].points[k]));
        });
        if (this.groups.length > 1 && d > bestD) {
          bestD = d;
          best = k;
        }
      });
      return pts[best];
    });
  }

  renderList() {
    const list = $('ik-solutions');
    list.replaceChildren();
    this.ghosts.forEach((g, i) => {
      const b = g.branch;
      const bits = [b ? `shoulder ${b.shoulder} · elbow ${b.elbow} · wrist ${b.wrist}` : 'no branch'];
      if (g.singular.length) bits.push(`singular: ${g.singular.join(', ')}`);
      bits.push(`${Number.isFinite(g.distance) ? g.distance.toFixed(3) : '?'} rad from the seed`);
      const swatch = document.createElement('span');
      swatch.className = 'swatch';
      swatch.style.background = `hsl(${hue(g.group)}, 65%, 45%)`;
      const btn = document.createElement('button');
      btn.type = 'button';
      btn.className = 'solution';
      btn.dataset.index = String(i);
      btn.dataset.joints = JSON.stringify(g.joints);
      btn.setAttribute('aria-pressed', 'false');
      const head = document.createElement('strong');
      head.textContent = `#${i + 1}`;
      const joints = document.createElement('code');
      joints.textContent = `[${g.joints.map(jointText).join(', ')}]`;
      btn.append(swatch, head, document.createTextNode(` ${bits.join(' · ')} `), joints);
      const li = document.createElement('li');
      li.append(btn);
      list.append(li);
    });
  }

  /** Moves the arm to solution `i` and marks it. */
  select(i) {
    const g = this.ghosts[i];
    if (!g) return;
    this.selected = i;
    $('ik-all-status').dataset.selected = String(i);
    for (const btn of $('ik-solutions').querySelectorAll('button[data-index]')) {
      btn.setAttribute('aria-pressed', String(Number(btn.dataset.index) === i));
    }
    this.host.moveTo(g.joints);
    this.redraw();
  }

  /** A click on the canvas: the nearest label, else the nearest ghost link within 10 px. */
  pick(x, y) {
    if (!this.ghosts.length) return;
    let group = -1;
    let best = Infinity;
    for (const h of this.hits) {
      const l = h.label;
      if (l && Math.abs(x - l.x) <= l.w / 2 + 3 && Math.abs(y - l.y) <= 10) {
        const d = Math.hypot(x - l.x, y - l.y);
        if (d < best) [best, group] = [d, h.group];
      }
    }
    if (group < 0) {
      for (const h of this.hits) {
        for (const [a, b] of h.segs) {
          const d = segDistance([x, y], a, b);
          if (d <= 10 && d < best) [best, group] = [d, h.group];
        }
      }
    }
    if (group < 0) return;
    // Repeated clicks on a group of 2π copies step through them.
    const members = this.groups[group];
    const at = members.indexOf(this.selected);
    this.select(members[at >= 0 ? (at + 1) % members.length : 0]);
  }

  /** The view layer: one thin translucent arm per group (over the real one), the selected one darker, labels on top. */
  draw(b, view) {
    const ctx = view.ctx;
    const d = view.canvas.dataset;
    this.hits = [];
    if (!this.ghosts.length) {
      delete d.ghosts;
      delete d.ghostLabels;
      return;
    }
    const selGroup = this.selected >= 0 ? this.ghosts[this.selected].group : -1;
    const order = this.groups.map((_, g) => g).filter((g) => g !== selGroup);
    if (selGroup >= 0) order.push(selGroup);
    const width = view.size * 0.035;
    ctx.save();
    ctx.lineCap = 'round';
    for (const g of order) {
      const ghost = this.ghosts[this.groups[g][0]];
      const hit = { group: g, segs: [], label: null };
      const alpha = g === selGroup ? 0.7 : 0.3;
      ctx.strokeStyle = `hsla(${hue(g)}, 65%, 45%, ${alpha})`;
      const line = (p, q, w) => {
        const s = view.segment(b, p, q);
        if (!s) return;
        ctx.lineWidth = w(s);
        ctx.beginPath();
        ctx.moveTo(s.a[0], s.a[1]);
        ctx.lineTo(s.b[0], s.b[1]);
        ctx.stroke();
        hit.segs.push([s.a, s.b]);
      };
      for (let i = 0; i + 1 < ghost.chain.length; i++) {
        line(ghost.chain[i], ghost.chain[i + 1], (s) => Math.min(Math.max(view.pixelsPerUnit(b, s.depth) * width * 0.45, 2), 12));
      }
      for (const [p, q] of ghost.stubs) line(p, q, () => 2);
      this.hits.push(hit);
    }
    ctx.font = '600 12px system-ui, sans-serif';
    ctx.textBaseline = 'middle';
    ctx.textAlign = 'center';
    for (const hit of this.hits) {
      const c = view.toCam(b, this.labelAt[hit.group]);
      if (!view.ortho && c[2] < b.near) continue;
      const [sx, sy] = view.toScreen(b, c);
      const text = groupText(this.groups[hit.group]);
      const w = ctx.measureText(text).width + 8;
      const x = sx + w / 2 + 6;
      const y = sy - 12;
      ctx.fillStyle = 'rgba(255,255,255,0.9)';
      ctx.fillRect(x - w / 2, y - 8, w, 16);
      ctx.fillStyle = `hsl(${hue(hit.group)}, 65%, 32%)`;
      ctx.fillText(text, x, y);
      hit.label = { x, y, w };
    }
    ctx.restore();
    d.ghosts = String(this.ghosts.length);
    d.ghostLabels = JSON.stringify(this.hits.filter((h) => h.label).map((h) => [h.label.x, h.label.y, this.groups[h.group][0]]));
  }
}
