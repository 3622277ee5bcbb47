// kinserve playground: REST and WebSocket client.
// No third-party code; all server strings are returned as plain data and the
// caller puts them into the page with textContent only.

/** An HTTP failure carrying the RFC 9457 problem document (or a stand-in). */
export class ApiError extends Error {
  constructor(status, problem) {
    const p = problem && typeof problem === 'object' ? problem : {};
    super(String(p.detail || p.title || `HTTP ${status}`));
    this.name = 'ApiError';
    this.status = status;
    this.problem = {
      type: typeof p.type === 'string' ? p.type : 'about:blank',
      title: typeof p.title === 'string' ? p.title : '',
      status: typeof p.status === 'number' ? p.status : status,
      detail: typeof p.detail === 'string' ? p.detail : '',
      errors: normalizeFieldErrors(p.errors),
    };
  }
}

/** Field errors as `[{field, message}]` with string members, whatever came in. */
export function normalizeFieldErrors(errors) {
  if (!Array.isArray(errors)) return [];
  return errors
    .filter((e) => e && typeof e === 'object')
    .map((e) => ({
      field: typeof e.field === 'string' ? e.field : String(e.field ?? ''),
      message: typeof e.message === 'string' ? e.message : String(e.message ?? ''),
    }));
}

async function readBody(resp) {
  const text = await resp.text();
  if (!text) return null;
  try {
    return JSON.parse(text);
  } catch {
    return { detail: text.slice(0, 500) };
  }
}

async function request(method, path, { body, headers = {}, signal } = {}) {
  const init = { method, headers: { Accept: 'application/json', ...headers }, signal };
  if (body !== undefined) {
    init.body = typeof body === 'string' ? body : JSON.stringify(body);
    if (!init.headers['Content-Type']) init.headers['Content-Type'] = 'application/json';
  }
  let resp;
  try {
    resp = await fetch(path, init);
  } catch (err) {
    if (err && err.name === 'AbortError') throw err;
    throw new ApiError(0, { title: 'Network error', detail: `Network error: ${err && err.message ? err.message : err}` });
  }
  const data = await readBody(resp);
  if (!resp.ok) {
    const problem = data && typeof data === 'object' ? { ...data } : {};
    if (!problem.detail && !problem.title) problem.title = `${resp.status} ${resp.statusText}`.trim();
    const err = new ApiError(resp.status, problem);
    err.retryAfterMs = retryAfterMs(resp.headers.get('Retry-After'));
    throw err;
  }
  return { status: resp.status, statusText: resp.statusText, data };
}

// ------------------------------------------------------- compute requests --
// The server runs batches, IK, closed forms and URDF imports on a compute pool
// of which one client (an IP address) holds at most a share — with the
// defaults on a server of up to four cores, one computation — and refuses past
// it at once (503 `overloaded` + Retry-After). So the page sends those
// requests one at a time (its own requests never refuse each other), and such
// a refusal (another tab at the same address, or this page's WebSocket IK
// holding the share) is retried after Retry-After, up to POOL_RETRIES times.
// Other 503s (a timeout, shutting down) are not retried. A request whose
// signal aborts leaves the lane at once.
const POOL_RETRIES = 4;
const OVERLOADED = 'urn:kinserve:problem:overloaded';
let poolLane = Promise.resolve();

/** Retry-After (seconds) as a wait in ms: 1 s when absent, at most 5 s. */
function retryAfterMs(header) {
  const s = Number(header);
  return header !== null && Number.isFinite(s) && s >= 0 ? Math.min(s, 5) * 1000 : 1000;
}

const abortError = () => new DOMException('Aborted', 'AbortError');

/** `promise`, or a rejection as soon as `signal` aborts. */
function unlessAborted(promise, signal) {
  if (!signal) return promise;
  if (signal.aborted) return Promise.reject(abortError());
  return new Promise((resolve, reject) => {
    const onAbort = () => reject(abortError());
    signal.addEventListener('abort', onAbort, { once: true });
    const done = () => signal.removeEventListener('abort', onAbort);
    promise.then(
      (v) => { done(); resolve(v); },
      (e) => { done(); reject(e); },
    );
  });
}

const pause = (ms, signal) => unlessAborted(new Promise((resolve) => setTimeout(resolve, ms)), signal);

/** `request` on the page's compute lane: after the one before it, an overload retried. */
function pooled(method, path, opts = {}) {
  const { signal } = opts;
  const task = async () => {
    for (let attempt = 0; ; attempt += 1) {
      if (signal && signal.aborted) throw abortError();
      try {
        return await request(method, path, opts);
      } catch (err) {
        const refused = err instanceof ApiError && err.problem.type === OVERLOADED;
        if (!refused || attempt >= POOL_RETRIES) throw err;
        await pause(err.retryAfterMs, signal);
      }
    }
  };
  const run = poolLane.then(task, task);
  poolLane = run.catch(() => undefined);
  return unlessAborted(run, signal);
}

const robotPath = (name) => `/v1/robots/${encodeURIComponent(name)}`;

/** `GET /v1/robots` → array of summaries. */
export async function listRobots(signal) {
  const { data } = await request('GET', '/v1/robots', { signal });
  return data && Array.isArray(data.robots) ? data.robots : [];
}

/** `GET /v1/robots/{name}` → the robot model. */
export async function getRobot(name, signal) {
  const { data } = await request('GET', robotPath(name), { signal });
  if (!data || typeof data !== 'object' || !Array.isArray(data.links)) {
    throw new ApiError(0, { detail: `Unexpected model for robot '${name}'` });
  }
  return data;
}

/** `POST /v1/robots/{name}/fk/batch` with joints in degrees (revolute). */
export async function fkBatch(name, configurations, signal) {
  const { data } = await pooled('POST', `${robotPath(name)}/fk/batch`, {
    body: { configurations, angle_unit: 'deg' },
    signal,
  });
  return data;
}

/** `POST /v1/robots/{name}/jacobian/batch` with joints in degrees (revolute). */
export async function jacobianBatch(name, configurations, signal) {
  const { data } = await pooled('POST', `${robotPath(name)}/jacobian/batch`, {
    body: { configurations, angle_unit: 'deg' },
    signal,
  });
  return data;
}

/** `POST /v1/robots/{name}/fk` of one configuration (degrees) with every frame. */
export async function fkFrames(name, joints, signal) {
  const { data } = await request('POST', `${robotPath(name)}/fk`, {
    body: { joints, angle_unit: 'deg', frames: true },
    signal,
  });
  return data;
}

/** `POST /v1/robots/{name}/ik` with `body` as given (a 422 is an `ApiError`). */
export async function solveIk(name, body, signal) {
  const { data } = await pooled('POST', `${robotPath(name)}/ik`, { body, signal });
  return data;
}

/** `POST /v1/robots/{name}/ik/path` with `body` as given. */
export async function ikPath(name, body, signal) {
  const { data } = await pooled('POST', `${robotPath(name)}/ik/path`, { body, signal });
  return data;
}

/** `GET /v1/robots/{name}/closed-form`: the DH table as closed-form FK. */
export async function closedForm(name, signal) {
  const { data } = await pooled('GET', `${robotPath(name)}/closed-form`, { signal });
  return data;
}

/** The text to show for a failure: the problem's detail (and field errors), or the message. */
export function problemText(err) {
  if (err instanceof ApiError) {
    const p = err.problem;
    const head = p.detail || p.title || `HTTP ${err.status}`;
    const fields = p.errors.map((e) => (e.field ? `${e.field}: ${e.message}` : e.message)).join('; ');
    return fields && !head.includes(fields) ? `${head} (${fields})` : head;
  }
  return String(err && err.message ? err.message : err);
}

/** `PUT /v1/robots/{name}` with the model text as typed; resolves `{status, statusText, data}`. */
export async function putRobot(name, modelText, token) {
  const headers = { 'Content-Type': 'application/json' };
  if (token) headers.Authorization = `Bearer ${token}`;
  return request('PUT', robotPath(name), { body: modelText, headers });
}

/**
 * `PUT /v1/robots/{name}?tip_link=…&convention=…` with a URDF document
 * (`application/xml`): the server imports it as a DH table.
 */
export async function importUrdf(name, urdf, { tipLink, convention, token } = {}) {
  const q = new URLSearchParams();
  if (tipLink) q.set('tip_link', tipLink);
  if (convention) q.set('convention', convention);
  const headers = { 'Content-Type': 'application/xml' };
  if (token) headers.Authorization = `Bearer ${token}`;
  const query = q.toString();
  return pooled('PUT', `${robotPath(name)}${query ? `?${query}` : ''}`, { body: urdf, headers });
}

/**
 * Live FK over `ws(s)://host/v1/robots/{name}/fk/stream`.
 *
 * At most one request is in flight. `update(joints)` only remembers the newest
 * joints while a request is outstanding; they are sent when its reply arrives.
 * The socket reconnects (with back-off) when it closes, and resends the newest
 * joints. `close()` stops it for good (used when the robot changes).
 */
export class FkStream {
  /**
   * One WebSocket per robot, one message in flight, newest request wins.
   * Three kinds of request share it, by priority: IK (`solveIk`), FK of the
   * shown joints with the Jacobian (`update`), FK of a ghost configuration
   * (`ghost`, the best attempt of a failed IK).
   */
  constructor(robotName, { onReply, onStatus, onIk, onGhost } = {}) {
    this.robotName = robotName;
    this.onReply = onReply || (() => {});
    this.onStatus = onStatus || (() => {});
    this.onIk = onIk || (() => {});
    this.onGhost = onGhost || (() => {});
    this.ws = null;
    this.closed = false;
    this.nextId = 1;
    this.inFlight = null; // {id, kind, joints?, ik?}
    this.latest = null; // newest joints asked for
    this.dirty = false; // latest not yet sent
    this.ik = null; // newest IK request not yet sent
    this.ghostJoints = null; // newest ghost FK not yet sent
    this.backoff = 250;
    this.timer = null;
    this.connect();
  }

  url() {
    const scheme = location.protocol === 'https:' ? 'wss:' : 'ws:';
    return `${scheme}//${location.host}${robotPath(this.robotName)}/fk/stream`;
  }

  connect() {
    if (this.closed) return;
    this.onStatus('connecting');
    let ws;
    try {
      ws = new WebSocket(this.url());
    } catch (err) {
      this.onStatus('error', String(err && err.message ? err.message : err));
      this.scheduleReconnect();
      return;
    }
    this.ws = ws;
    ws.addEventListener('open', () => {
      if (this.ws !== ws || this.closed) return;
      this.backoff = 250;
      this.onStatus('open');
      this.inFlight = null;
      if (this.latest) this.dirty = true;
      this.pump();
    });
    ws.addEventListener('message', (ev) => {
      if (this.ws !== ws || this.closed) return;
      this.handleMessage(ev.data);
    });
    ws.addEventListener('close', () => {
      if (this.ws !== ws) return;
      this.ws = null;
      if (this.inFlight && this.inFlight.kind === 'fk') this.dirty = true; // its reply is lost: resend the newest joints
      this.inFlight = null;
      if (this.closed) return;
      this.onStatus('closed');
      this.scheduleReconnect();
    });
    ws.addEventListener('error', () => {
      // A 'close' event always follows; nothing else to do here.
    });
  }

  scheduleReconnect() {
    if (this.closed || this.timer) return;
    const delay = this.backoff;
    this.backoff = Math.min(this.backoff * 2, 5000);
    this.timer = setTimeout(() => {
      this.timer = null;
      this.connect();
    }, delay);
  }

  handleMessage(data) {
    let msg;
    try {
      msg = JSON.parse(typeof data === 'string' ? data : '');
    } catch {
      msg = { error: { title: 'Bad reply', detail: 'The server sent a reply that is not JSON.' } };
    }
    if (!msg || typeof msg !== 'object') msg = { error: { detail: 'Empty reply' } };
    const req = this.inFlight;
    this.inFlight = null;
    try {
      if (req && req.kind === 'ik') this.onIk(msg, req.ik);
      else if (req && req.kind === 'ghost') this.onGhost(msg, req.joints);
      else this.onReply(msg, req ? req.joints : null);
    } finally {
      this.pump();
    }
  }

  /** Ask for FK of `joints` (revolute in degrees, prismatic in model length unit). */
  update(joints) {
    this.latest = joints.slice();
    this.dirty = true;
    this.pump();
  }

  /** Ask for IK: `ik` is the body of `POST …/ik` (seed and answer in degrees). */
  solveIk(ik) {
    this.ik = ik;
    this.pump();
  }

  /** Ask for the frames of `joints` to draw as a ghost (degrees). */
  ghost(joints) {
    this.ghostJoints = joints.slice();
    this.pump();
  }

  /** The next message to send, newest of the most urgent kind, or null. */
  next(id) {
    if (this.ik) {
      const ik = this.ik;
      this.ik = null;
      return { req: { id, kind: 'ik', ik }, msg: { id, ik } };
    }
    if (this.dirty && this.latest) {
      const joints = this.latest;
      this.dirty = false;
      return { req: { id, kind: 'fk', joints }, msg: { id, joints, angle_unit: 'deg', frames: true, jacobian: true } };
    }
    if (this.ghostJoints) {
      const joints = this.ghostJoints;
      this.ghostJoints = null;
      return { req: { id, kind: 'ghost', joints }, msg: { id, joints, angle_unit: 'deg', frames: true } };
    }
    return null;
  }

  pump() {
    if (this.closed || this.inFlight) return;
    const ws = this.ws;
    if (!ws || ws.readyState !== WebSocket.OPEN) return;
    const id = this.nextId++;
    const out = this.next(id);
    if (!out) return;
    this.inFlight = out.req;
    try {
      ws.send(JSON.stringify(out.msg));
    } catch (err) {
      this.inFlight = null;
      if (out.req.kind === 'fk') this.dirty = true;
      this.onStatus('error', String(err && err.message ? err.message : err));
    }
  }

  close() {
    this.closed = true;
    if (this.timer) clearTimeout(this.timer);
    this.timer = null;
    const ws = this.ws;
    this.ws = null;
    if (ws) {
      try {
        ws.close(1000, 'robot changed');
      } catch {
        /* already closing */
      }
    }
  }
}
