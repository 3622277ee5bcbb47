// kinserve playground: a small 3D view of a serial chain, drawn with Canvas 2D.
// Z is up. Orbit by dragging (mouse or touch), pan with shift/right drag,
// zoom with the wheel or a pinch, keyboard: arrows orbit, +/- zoom, f fits.
// Dragging the tool triad moves an IK target in the view plane (onToolDrag);
// with the tool selected, alt+arrows and PageUp/PageDown nudge it (onToolNudge).
// A failed IK's best attempt is drawn as a ghost (setGhost). Other modules
// draw through `layers` (functions of the camera basis and the view, drawn
// over the arm) and hear clicks that neither drag nor orbit (`onPick`).

const DEG = Math.PI / 180;

const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const norm = (a) => {
  const l = Math.hypot(a[0], a[1], a[2]) || 1;
  return [a[0] / l, a[1] / l, a[2] / l];
};

/** Largest of 1, 2, 5 × 10^k not above `x`. */
function niceStep(x) {
  if (!(x > 0) || !Number.isFinite(x)) return 1;
  const p = Math.pow(10, Math.floor(Math.log10(x)));
  const f = x / p;
  return (f >= 5 ? 5 : f >= 2 ? 2 : 1) * p;
}

/** Origin and axes of a 4×4 row-major pose matrix (array of rows), or null. */
export function frameOf(matrix) {
  if (!Array.isArray(matrix) || matrix.length < 3) return null;
  const r = (i, j) => Number(matrix[i] && matrix[i][j]);
  const o = [r(0, 3), r(1, 3), r(2, 3)];
  if (!o.every(Number.isFinite)) return null;
  return {
    o,
    x: [r(0, 0), r(1, 0), r(2, 0)],
    y: [r(0, 1), r(1, 1), r(2, 1)],
    z: [r(0, 2), r(1, 2), r(2, 2)],
  };
}

export class View3D {
  constructor(canvas) {
    this.canvas = canvas;
    let ctx = null;
    try {
      ctx = canvas && canvas.getContext ? canvas.getContext('2d') : null;
    } catch {
      ctx = null;
    }
    this.ctx = ctx;
    this.frames = []; // [{o,x,y,z}]
    this.tool = null;
    this.ghost = null; // {frames, tool} of a failed IK's best attempt
    this.target = null; // [x,y,z] of the IK target being dragged
    this.toolSelected = false;
    this.onToolDrag = null; // (position) => void, while the tool is dragged
    this.onToolNudge = null; // (delta) => void, keys with the tool selected
    this.layers = []; // [(basis, view) => void], drawn over the arm (translucent), under the target ring
    this.onPick = null; // (x, y) => void: a click (CSS px in the canvas) that did not move
    this.cloud = null; // Float64Array [x,y,z,...]
    this.unit = 'm';
    this.size = 1; // characteristic length of the robot
    this.ortho = false;
    this.fovY = 45 * DEG;
    this.cam = { target: [0, 0, 0.5], yaw: 35 * DEG, pitch: 25 * DEG, dist: 3 };
    this.pointers = new Map();
    this.pending = false;
    this.cssW = 0;
    this.cssH = 0;
    this.wantFit = true;
    if (!ctx) return;
    this.installInput();
    this.resize();
    if (typeof ResizeObserver === 'function') {
      this.ro = new ResizeObserver(() => this.resize());
      this.ro.observe(canvas);
    } else {
      window.addEventListener('resize', () => this.resize());
    }
  }

  get available() {
    return !!this.ctx;
  }

  /** New robot: units and a characteristic length (for grid, triads, first fit). */
  setRobot({ unit, size, baseOrigin }) {
    this.unit = unit || 'm';
    this.size = size > 0 && Number.isFinite(size) ? size : this.unit === 'mm' ? 1000 : 1;
    this.frames = [];
    this.tool = null;
    this.ghost = null;
    this.target = null;
    this.toolSelected = false;
    this.cloud = null;
    const b = baseOrigin || [0, 0, 0];
    this.cam.target = [b[0], b[1], b[2] + this.size * 0.4];
    this.cam.dist = this.size * 3;
    this.wantFit = true;
    this.redraw();
  }

  /** Frames from an FK reply (`frames` poses and the tool `pose`). */
  setPose(framePoses, toolPose) {
    this.frames = (Array.isArray(framePoses) ? framePoses : []).map((p) => frameOf(p && p.matrix)).filter(Boolean);
    this.tool = toolPose ? frameOf(toolPose.matrix) : null;
    if (this.wantFit && (this.frames.length || this.tool)) {
      this.wantFit = false;
      this.fit();
    }
    this.redraw();
  }

  /** The best attempt of a failed IK, drawn ghosted (null clears it). */
  setGhost(framePoses, toolPose) {
    if (!framePoses) {
      this.ghost = null;
    } else {
      const frames = framePoses.map((p) => frameOf(p && p.matrix)).filter(Boolean);
      this.ghost = { frames, tool: toolPose ? frameOf(toolPose.matrix) : null };
    }
    this.redraw();
  }

  /** The IK target marker (null hides it). */
  setTarget(p) {
    this.target = Array.isArray(p) ? p.slice() : null;
    this.redraw();
  }

  /** Screen position of the tool origin, or null. */
  toolOnScreen() {
    if (!this.tool) return null;
    const b = this.basis();
    const c = this.toCam(b, this.tool.o);
    if (!this.ortho && c[2] < b.near) return null;
    return this.toScreen(b, c);
  }

  /** World displacement of a screen drag (dx, dy px) at the tool's depth, in the view plane. */
  dragDelta(dx, dy, at) {
    const b = this.basis();
    const k = 1 / this.pixelsPerUnit(b, this.toCam(b, at)[2]);
    return add(scale(b.r, dx * k), scale(b.u, -dy * k));
  }

  /** Workspace cloud as an array of [x,y,z] (or null to clear). */
  setCloud(points) {
    if (!points || !points.length) {
      this.cloud = null;
    } else {
      const a = new Float64Array(points.length * 3);
      points.forEach((p, i) => {
        a[i * 3] = p[0];
        a[i * 3 + 1] = p[1];
        a[i * 3 + 2] = p[2];
      });
      this.cloud = a;
      let zmin = Infinity;
      let zmax = -Infinity;
      for (let i = 2; i < a.length; i += 3) {
        zmin = Math.min(zmin, a[i]);
        zmax = Math.max(zmax, a[i]);
      }
      this.cloudZ = [zmin, zmax];
    }
    this.redraw();
  }

  setOrtho(on) {
    this.ortho = !!on;
    this.redraw();
  }

  /** Fit the camera to the robot and the workspace cloud. */
  fit() {
    const pts = [];
    for (const f of this.frames) pts.push(f.o);
    if (this.tool) pts.push(this.tool.o);
    if (this.cloud) {
      const c = this.cloud;
      for (let i = 0; i < c.length; i += 3) pts.push([c[i], c[i + 1], c[i + 2]]);
    }
    if (!pts.length) return;
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    for (const p of pts) {
      for (let k = 0; k < 3; k++) {
        lo[k] = Math.min(lo[k], p[k]);
        hi[k] = Math.max(hi[k], p[k]);
      }
    }
    const center = scale(add(lo, hi), 0.5);
    let r = 0;
    for (const p of pts) r = Math.max(r, Math.hypot(...sub(p, center)));
    r = Math.max(r, this.size * 0.15) * 1.12 + this.size * 0.08; // room for triads and labels
    const aspect = this.cssW > 0 && this.cssH > 0 ? this.cssW / this.cssH : 1.5;
    const halfV = this.fovY / 2;
    const halfH = Math.atan(Math.tan(halfV) * aspect);
    const half = Math.min(halfV, halfH);
    this.cam.target = center;
    this.cam.dist = r / Math.sin(half);
    this.redraw();
  }

  resize() {
    if (!this.ctx) return;
    const rect = this.canvas.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(rect.width));
    const h = Math.max(1, Math.round(rect.height));
    if (w === this.cssW && h === this.cssH && this.dpr === dpr) return;
    this.cssW = w;
    this.cssH = h;
    this.dpr = dpr;
    this.canvas.width = Math.round(w * dpr);
    this.canvas.height = Math.round(h * dpr);
    this.redraw();
  }

  redraw() {
    if (!this.ctx) return;
    // For automation: the drawn frame is behind the state until 'done'.
    this.canvas.dataset.drawn = 'pending';
    if (this.pending) return;
    this.pending = true;
    const run = () => {
      this.pending = false;
      try {
        this.draw();
      } catch (err) {
        // Never let a drawing fault escape into the console loop.
        this.lastError = err;
      }
    };
    if (typeof requestAnimationFrame === 'function') requestAnimationFrame(run);
    else setTimeout(run, 16);
  }

  // ---- camera -------------------------------------------------------------

  basis() {
    const { target, yaw, pitch, dist } = this.cam;
    const dir = [Math.cos(pitch) * Math.cos(yaw), Math.cos(pitch) * Math.sin(yaw), Math.sin(pitch)];
    const eye = add(target, scale(dir, dist));
    const f = norm(sub(target, eye));
    let r = cross(f, [0, 0, 1]);
    if (Math.hypot(...r) < 1e-9) r = [1, 0, 0];
    r = norm(r);
    const u = cross(r, f);
    const focal = this.cssH / 2 / Math.tan(this.fovY / 2);
    return { eye, f, r, u, focal, near: dist * 0.02 };
  }

  /** Camera coordinates of a world point: [right, up, depth]. */
  toCam(b, p) {
    const v = sub(p, b.eye);
    return [dot(v, b.r), dot(v, b.u), dot(v, b.f)];
  }

  toScreen(b, c) {
    const k = this.ortho ? b.focal / this.cam.dist : b.focal / c[2];
    return [this.cssW / 2 + c[0] * k, this.cssH / 2 - c[1] * k];
  }

  /** Screen coordinates of a segment clipped to the near plane, or null. */
  segment(b, p, q) {
    let a = this.toCam(b, p);
    let c = this.toCam(b, q);
    if (!this.ortho) {
      if (a[2] < b.near && c[2] < b.near) return null;
      if (a[2] < b.near || c[2] < b.near) {
        const t = (b.near - a[2]) / (c[2] - a[2]);
        const m = [a[0] + (c[0] - a[0]) * t, a[1] + (c[1] - a[1]) * t, b.near];
        if (a[2] < b.near) a = m;
        else c = m;
      }
    }
    return { a: this.toScreen(b, a), b: this.toScreen(b, c), depth: (a[2] + c[2]) / 2, za: a[2], zb: c[2] };
  }

  pixelsPerUnit(b, depth) {
    return this.ortho ? b.focal / this.cam.dist : b.focal / Math.max(depth, b.near);
  }

  // ---- drawing ------------------------------------------------------------

  draw() {
    const ctx = this.ctx;
    if (!ctx) return;
    const W = this.cssW;
    const H = this.cssH;
    ctx.setTransform(this.dpr || 1, 0, 0, this.dpr || 1, 0, 0);
    ctx.clearRect(0, 0, W, H);
    const bg = ctx.createLinearGradient(0, 0, 0, H);
    bg.addColorStop(0, '#f7f9fc');
    bg.addColorStop(1, '#e6ebf2');
    ctx.fillStyle = bg;
    ctx.fillRect(0, 0, W, H);
    const b = this.basis();

    const gridStep = this.drawGrid(b);
    this.drawCloud(b);
    if (this.ghost) this.drawGhost(b);
    this.drawRobot(b);
    for (const layer of this.layers) {
      try {
        layer(b, this);
      } catch (err) {
        this.lastError = err;
      }
    }
    this.drawTarget(b);
    this.drawOverlay(gridStep);
    // Where the tool handle is, for automation (and the browser test).
    const t = this.toolOnScreen();
    const d = this.canvas.dataset;
    if (t) {
      d.toolX = t[0].toFixed(1);
      d.toolY = t[1].toFixed(1);
    } else {
      delete d.toolX;
      delete d.toolY;
    }
    d.drawn = 'done';
    d.ghost = this.ghost ? 'shown' : '';
  }

  drawGrid(b) {
    const ctx = this.ctx;
    const base = this.frames[0] ? this.frames[0].o : [0, 0, 0];
    const extent = Math.max(this.size * 1.4, 1e-9);
    const step = niceStep(extent / 6);
    const n = Math.ceil(extent / step);
    const cx = Math.round(base[0] / step) * step;
    const cy = Math.round(base[1] / step) * step;
    ctx.lineCap = 'butt';
    for (let i = -n; i <= n; i++) {
      const major = i === 0;
      ctx.strokeStyle = major ? 'rgba(60,70,90,0.45)' : 'rgba(60,70,90,0.16)';
      ctx.lineWidth = major ? 1.2 : 1;
      const x = cx + i * step;
      const y = cy + i * step;
      for (const [p, q] of [
        [[x, cy - n * step, 0], [x, cy + n * step, 0]],
        [[cx - n * step, y, 0], [cx + n * step, y, 0]],
      ]) {
        const s = this.segment(b, p, q);
        if (!s) continue;
        ctx.beginPath();
        ctx.moveTo(s.a[0], s.a[1]);
        ctx.lineTo(s.b[0], s.b[1]);
        ctx.stroke();
      }
    }
    return step;
  }

  drawCloud(b) {
    const c = this.cloud;
    if (!c) return;
    const ctx = this.ctx;
    const [zmin, zmax] = this.cloudZ || [0, 1];
    const span = zmax - zmin || 1;
    for (let i = 0; i < c.length; i += 3) {
      const p = [c[i], c[i + 1], c[i + 2]];
      const q = this.toCam(b, p);
      if (!this.ortho && q[2] < b.near) continue;
      const s = this.toScreen(b, q);
      const t = (c[i + 2] - zmin) / span;
      const hue = Math.round(250 - 210 * t);
      ctx.fillStyle = `hsla(${hue}, 75%, 45%, 0.55)`;
      ctx.fillRect(s[0] - 1.5, s[1] - 1.5, 3, 3);
    }
  }

  drawRobot(b) {
    const ctx = this.ctx;
    const items = [];
    const frames = this.frames;
    const size = this.size;
    const linkWidth = size * 0.035;
    const chain = frames.map((f) => f.o);
    if (this.tool) {
      const last = chain[chain.length - 1];
      if (!last || Math.hypot(...sub(this.tool.o, last)) > size * 1e-6) chain.push(this.tool.o);
    }
    for (let i = 0; i + 1 < chain.length; i++) {
      const s = this.segment(b, chain[i], chain[i + 1]);
      if (!s) continue;
      const isTool = this.tool && i + 1 === chain.length - 1 && chain.length > frames.length;
      const px = this.pixelsPerUnit(b, s.depth) * linkWidth * (isTool ? 0.6 : 1);
      items.push({
        depth: s.depth,
        draw: () => {
          ctx.lineCap = 'round';
          ctx.strokeStyle = isTool ? '#8a6d3b' : '#50607a';
          ctx.lineWidth = Math.min(Math.max(px, 2.5), 28);
          ctx.beginPath();
          ctx.moveTo(s.a[0], s.a[1]);
          ctx.lineTo(s.b[0], s.b[1]);
          ctx.stroke();
          ctx.strokeStyle = 'rgba(255,255,255,0.35)';
          ctx.lineWidth = Math.max(1, ctx.lineWidth * 0.25);
          ctx.stroke();
        },
      });
    }
    // joints / frame origins
    frames.forEach((f, i) => {
      const c = this.toCam(b, f.o);
      if (!this.ortho && c[2] < b.near) return;
      const s = this.toScreen(b, c);
      const rad = Math.min(Math.max(this.pixelsPerUnit(b, c[2]) * linkWidth * 0.75, 3), 18);
      items.push({
        depth: c[2] - 1e-9,
        draw: () => {
          ctx.fillStyle = i === 0 ? '#2b3445' : '#e8ecf2';
          ctx.strokeStyle = '#2b3445';
          ctx.lineWidth = 1.5;
          ctx.beginPath();
          ctx.arc(s[0], s[1], rad, 0, Math.PI * 2);
          ctx.fill();
          ctx.stroke();
        },
      });
    });
    // triads
    const triads = frames.map((f, i) => ({ f, len: size * (i === 0 ? 0.14 : 0.08), w: i === 0 ? 2.5 : 1.6 }));
    if (this.tool) triads.push({ f: this.tool, len: size * 0.12, w: 2.5 });
    const colors = ['#d62728', '#2ca02c', '#1f5fd6'];
    for (const t of triads) {
      ['x', 'y', 'z'].forEach((axis, k) => {
        const end = add(t.f.o, scale(t.f[axis], t.len));
        const s = this.segment(b, t.f.o, end);
        if (!s) return;
        items.push({
          depth: s.depth - size * 1e-3,
          draw: () => {
            ctx.lineCap = 'round';
            ctx.strokeStyle = colors[k];
            ctx.lineWidth = t.w;
            ctx.beginPath();
            ctx.moveTo(s.a[0], s.a[1]);
            ctx.lineTo(s.b[0], s.b[1]);
            ctx.stroke();
          },
        });
      });
    }
    items.sort((p, q) => q.depth - p.depth);
    for (const it of items) it.draw();

    // labels on top
    const labels = [];
    if (frames[0]) labels.push({ p: frames[0].o, text: 'base', color: '#2b3445' });
    if (frames.length > 1 && this.tool && Math.hypot(...sub(this.tool.o, frames[frames.length - 1].o)) > size * 1e-3) {
      labels.push({ p: frames[frames.length - 1].o, text: 'flange', color: '#50607a' });
    }
    if (this.tool) labels.push({ p: this.tool.o, text: 'tool', color: '#8a4b00' });
    ctx.font = '600 12px system-ui, sans-serif';
    ctx.textBaseline = 'middle';
    for (const l of labels) {
      const c = this.toCam(b, l.p);
      if (!this.ortho && c[2] < b.near) continue;
      const s = this.toScreen(b, c);
      const x = s[0] + 10;
      const y = s[1] - 12;
      const w = ctx.measureText(l.text).width;
      ctx.fillStyle = 'rgba(255,255,255,0.85)';
      ctx.fillRect(x - 3, y - 8, w + 6, 16);
      ctx.fillStyle = l.color;
      ctx.fillText(l.text, x, y);
    }
  }

  /** The ghost: links and tool of the best attempt, dashed and translucent. */
  drawGhost(b) {
    const ctx = this.ctx;
    const chain = this.ghost.frames.map((f) => f.o);
    if (this.ghost.tool) chain.push(this.ghost.tool.o);
    ctx.save();
    ctx.setLineDash([6, 4]);
    ctx.strokeStyle = 'rgba(200, 60, 40, 0.55)';
    ctx.lineWidth = 3;
    for (let i = 0; i + 1 < chain.length; i++) {
      const s = this.segment(b, chain[i], chain[i + 1]);
      if (!s) continue;
      ctx.beginPath();
      ctx.moveTo(s.a[0], s.a[1]);
      ctx.lineTo(s.b[0], s.b[1]);
      ctx.stroke();
    }
    ctx.restore();
  }

  /** A ring at the IK target, and a ring round the tool when it is selected. */
  drawTarget(b) {
    const ctx = this.ctx;
    const ring = (p, color, r) => {
      const c = this.toCam(b, p);
      if (!this.ortho && c[2] < b.near) return;
      const s = this.toScreen(b, c);
      ctx.strokeStyle = color;
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(s[0], s[1], r, 0, Math.PI * 2);
      ctx.stroke();
    };
    if (this.target) ring(this.target, '#c0392b', 9);
    if (this.toolSelected && this.tool) ring(this.tool.o, '#8a4b00', 14);
  }

  drawOverlay(gridStep) {
    const ctx = this.ctx;
    const H = this.cssH;
    ctx.font = '12px system-ui, sans-serif';
    ctx.textBaseline = 'alphabetic';
    ctx.fillStyle = '#3b4658';
    ctx.fillText(`grid: ${formatLen(gridStep)} ${this.unit}  ·  Z up  ·  ${this.ortho ? 'orthographic' : 'perspective'}`, 10, H - 10);
    const lx = 10;
    const ly = 18;
    [['x', '#d62728'], ['y', '#2ca02c'], ['z', '#1f5fd6']].forEach(([t, c], i) => {
      ctx.fillStyle = c;
      ctx.fillRect(lx + i * 30, ly - 8, 10, 3);
      ctx.fillText(t, lx + i * 30 + 13, ly - 3);
    });
    if (!this.frames.length && !this.tool) {
      ctx.fillStyle = '#6b7689';
      ctx.fillText('waiting for FK…', 10, 40);
    }
  }

  // ---- input --------------------------------------------------------------

  installInput() {
    const c = this.canvas;
    c.addEventListener('pointerdown', (e) => {
      const rect = c.getBoundingClientRect();
      const t = this.toolOnScreen();
      const onTool =
        !!t && !!this.onToolDrag && e.button === 0 && !e.shiftKey && this.pointers.size === 0 &&
        Math.hypot(e.clientX - rect.left - t[0], e.clientY - rect.top - t[1]) <= 16;
      this.toolSelected = onTool;
      const drag = onTool ? { at: this.tool.o.slice() } : null;
      this.pointers.set(e.pointerId, { x: e.clientX, y: e.clientY, x0: e.clientX, y0: e.clientY, button: e.button, shift: e.shiftKey, drag });
      if (onTool) this.redraw();
      try {
        c.setPointerCapture(e.pointerId);
      } catch {
        /* not capturable */
      }
      if (this.pointers.size === 2) this.pinch = this.pinchDistance();
      e.preventDefault();
    });
    const end = (e) => {
      this.pointers.delete(e.pointerId);
      this.pinch = this.pointers.size === 2 ? this.pinchDistance() : null;
    };
    c.addEventListener('pointerup', (e) => {
      const p = this.pointers.get(e.pointerId);
      const still = p && !p.drag && p.button === 0 && !p.shift && this.pointers.size === 1;
      end(e);
      if (still && this.onPick && Math.hypot(e.clientX - p.x0, e.clientY - p.y0) < 4) {
        const rect = c.getBoundingClientRect();
        this.onPick(e.clientX - rect.left, e.clientY - rect.top);
      }
    });
    c.addEventListener('pointercancel', end);
    c.addEventListener('lostpointercapture', end);
    c.addEventListener('pointermove', (e) => {
      const p = this.pointers.get(e.pointerId);
      if (!p) return;
      const dx = e.clientX - p.x;
      const dy = e.clientY - p.y;
      p.x = e.clientX;
      p.y = e.clientY;
      if (this.pointers.size >= 2) {
        const d = this.pinchDistance();
        if (this.pinch && d > 0) this.zoom(this.pinch / d);
        this.pinch = d;
        return;
      }
      if (p.drag) {
        p.drag.at = add(p.drag.at, this.dragDelta(dx, dy, p.drag.at));
        this.setTarget(p.drag.at);
        this.onToolDrag(p.drag.at.slice());
      } else if (p.button === 2 || p.button === 1 || e.shiftKey) this.pan(dx, dy);
      else this.orbit(dx, dy);
    });
    c.addEventListener(
      'wheel',
      (e) => {
        e.preventDefault();
        const unit = e.deltaMode === 1 ? 33 : e.deltaMode === 2 ? 400 : 1;
        this.zoom(Math.exp(e.deltaY * unit * 0.0015));
      },
      { passive: false },
    );
    c.addEventListener('contextmenu', (e) => e.preventDefault());
    c.addEventListener('keydown', (e) => {
      const k = e.key;
      const step = this.size * 0.01;
      const nudge = {
        ArrowLeft: [-step, 0, 0],
        ArrowRight: [step, 0, 0],
        ArrowUp: [0, step, 0],
        ArrowDown: [0, -step, 0],
        PageUp: [0, 0, step],
        PageDown: [0, 0, -step],
      }[k];
      if (this.toolSelected && this.onToolNudge && nudge && (e.altKey || k.startsWith('Page'))) {
        this.onToolNudge(nudge);
        e.preventDefault();
        return;
      }
      if (k === 'Escape' && this.toolSelected) {
        this.toolSelected = false;
        this.redraw();
      } else if (k === 'ArrowLeft') this.orbit(-20, 0);
      else if (k === 'ArrowRight') this.orbit(20, 0);
      else if (k === 'ArrowUp') this.orbit(0, -20);
      else if (k === 'ArrowDown') this.orbit(0, 20);
      else if (k === '+' || k === '=') this.zoom(1 / 1.15);
      else if (k === '-' || k === '_') this.zoom(1.15);
      else if (k === 'f' || k === 'F') this.fit();
      else return;
      e.preventDefault();
    });
  }

  pinchDistance() {
    const ps = [...this.pointers.values()];
    if (ps.length < 2) return 0;
    return Math.hypot(ps[0].x - ps[1].x, ps[0].y - ps[1].y);
  }

  orbit(dx, dy) {
    this.cam.yaw -= dx * 0.01;
    this.cam.pitch = Math.min(Math.max(this.cam.pitch + dy * 0.01, -89 * DEG), 89 * DEG);
    this.redraw();
  }

  pan(dx, dy) {
    const b = this.basis();
    const k = this.cam.dist * Math.tan(this.fovY / 2) / (this.cssH / 2 || 1);
    this.cam.target = add(this.cam.target, add(scale(b.r, -dx * k), scale(b.u, dy * k)));
    this.redraw();
  }

  zoom(factor) {
    if (!(factor > 0) || !Number.isFinite(factor)) return;
    this.cam.dist = Math.min(Math.max(this.cam.dist * factor, this.size * 0.05), this.size * 200);
    this.redraw();
  }
}

/** Short length text for labels (no float noise). */
export function formatLen(x) {
  if (!Number.isFinite(x)) return String(x);
  return String(Number(x.toPrecision(6)));
}
