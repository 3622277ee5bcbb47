// The client against the real server (KINSERVE_URL, KINSERVE_TOKEN,
// KINSERVE_EXPECTED: values from the kinematics library, written by
// tests/api/clients.rs). Poses to 1e-9 against the library, 1e-12 against
// the server's own answers.
import { test } from "node:test";
import assert from "node:assert/strict";
import { createHash } from "node:crypto";
import { readFileSync } from "node:fs";

import { GENERATED_FROM, KinserveClient, KinserveError, OPERATIONS, canonicalJson, replyError, replyPath, type Answer, type Body, type Schemas, type WsReply } from "../src/index.js";
import * as readme from "./readme.generated.js";

const BASE = process.env.KINSERVE_URL ?? "http://127.0.0.1:8080";
const TOKEN = process.env.KINSERVE_TOKEN ?? "";
const EXPECTED = process.env.KINSERVE_EXPECTED ? (JSON.parse(readFileSync(process.env.KINSERVE_EXPECTED, "utf8")) as Expected) : undefined;
const IDLE_MS = Number(process.env.KINSERVE_STREAM_IDLE_MS ?? "0");

interface Expected {
  fk: { robot: string; joints: number[]; matrix: number[][] };
}

const client = new KinserveClient(BASE, { token: TOKEN });

function close(a: number[] | number[][], b: number[] | number[][], tol: number, what: string): void {
  const fa = a.flat(), fb = b.flat();
  assert.equal(fa.length, fb.length, what);
  fa.forEach((x, i) => assert.ok(Math.abs(x - (fb[i] ?? NaN)) <= tol, `${what}[${i}]: ${x} vs ${fb[i]}`));
}

test("built from the server's OpenAPI document", async () => {
  const live = await client.openapi();
  const sha = createHash("sha256").update(canonicalJson(live)).digest("hex");
  assert.equal(sha, GENERATED_FROM.openapiSha256, "the OpenAPI document changed: KINSERVE_UPDATE_CLIENTS=1 cargo test --test api clients, then npm run build");
  assert.equal(GENERATED_FROM.apiVersion, (live as { info: { version: string } }).info.version);
  const doc = live as { paths: Record<string, Record<string, { operationId: string }>> };
  const ids = Object.values(doc.paths).flatMap((p) => Object.values(p).map((o) => o.operationId));
  assert.deepEqual(new Set(ids), new Set(Object.keys(OPERATIONS)));
});

test("fk equals the kinematics library, batch formats equal the full pose", async () => {
  const q = EXPECTED?.fk.joints ?? [0.3, -0.4, 0.6, 0.2, -0.5, 0.7];
  const fk = await client.fk("puma560", { joints: q });
  assert.ok(fk.pose);
  if (EXPECTED) close(fk.pose.matrix, EXPECTED.fk.matrix, 1e-9, "matrix");
  const m = await client.fkBatch("puma560", { configurations: [q, q], pose_format: "matrix" });
  assert.ok(m.matrices);
  close(m.matrices[1] ?? [], fk.pose.matrix.slice(0, 3), 1e-12, "batch matrix");
  const deg = await client.fk("puma560", { joints: q.map((x) => (x * 180) / Math.PI), angle_unit: "deg" });
  close(deg.pose?.matrix ?? [], fk.pose.matrix, 1e-12, "deg");
});

test("fk batch packed: the JSON batch's doubles, bit for bit", async () => {
  const qs = [[0.3, -0.4, 0.6, 0.2, -0.5, 0.7], [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], [0, 0, 0, 0, 0, 0]];
  const json = await client.fkBatch("puma560", { configurations: qs, pose_format: "matrix" });
  const matrices = json.matrices ?? [];
  assert.equal(matrices.length, 3);
  const packed = await client.fkBatchPacked("puma560", new Float64Array(qs.flat()), { pose_format: "matrix" });
  assert.deepEqual([packed.poseFormat, packed.stride, packed.lengthUnit], ["matrix", 12, "m"]);
  assert.deepEqual(Array.from(packed.values), matrices.flat());
  const degrees = qs.flat().map((x) => (x * 180) / Math.PI);
  const pos = await client.fkBatchPacked("puma560", degrees, { pose_format: "position", angle_unit: "deg" });
  assert.equal(pos.stride, 3);
  close(Array.from(pos.values), matrices.map((m) => [m[3] ?? NaN, m[7] ?? NaN, m[11] ?? NaN]), 1e-12, "positions in degrees");
  // 42 values declared as 7 per configuration for the 6-joint PUMA: a 422 naming `joint_count`.
  await assert.rejects(client.fkBatchPacked("puma560", new Float64Array(42), { joint_count: 7 }), (e: unknown) => e instanceof KinserveError && e.status === 422 && "joint_count" in e.fields);
  // Not a whole number of 6-joint configurations: a 400 naming `body`.
  await assert.rejects(client.fkBatchPacked("puma560", [0.1, 0.2]), (e: unknown) => e instanceof KinserveError && e.status === 400 && "body" in e.fields);
});

test("jacobian, ik, link transforms, closed form", async () => {
  const q = [0.3, -0.4, 0.6, 0.2, -0.5, 0.7];
  const j = await client.jacobian("puma560", { joints: q });
  assert.equal(j.jacobian.length, 6);
  const jb = await client.jacobianBatch("puma560", { configurations: [q] });
  close(jb.results[0]?.jacobian ?? [], j.jacobian, 1e-12, "jacobian batch");
  const target = (await client.fk("puma560", { joints: q })).pose;
  assert.ok(target);
  const ik = await client.ik("puma560", { target: { matrix: target.matrix }, tolerance: 1e-10 });
  assert.ok(ik.converged);
  close((await client.fk("puma560", { joints: ik.joints })).pose?.matrix ?? [], target.matrix, 1e-8, "ik pose");
  const ikb = await client.ikBatch("planar_2dof", { targets: [{ position: [0.5, 0.3, 0] }], position_only: true });
  assert.ok(ikb.results[0]?.converged);
  const lt = await client.linkTransforms("planar_2dof", { joints: [0.5, 0.1] });
  assert.equal(lt.link_transforms.length, 2);
  const cf = await client.closedForm("planar_2dof");
  assert.deepEqual(cf.symbols, { a1: 0.4, a2: 0.3 });
});

test("robots: pages, register, replace and delete with ETags, URDF round trip", async () => {
  const all = (await client.listRobots({ page_size: 1000 })).robots.map((r) => r.name);
  const paged: string[] = [];
  for await (const r of client.robots(2)) paged.push(r.name);
  assert.deepEqual(paged, all);
  const model = {
    name: "ts-etag", convention: "standard" as const, angle_unit: "deg" as const,
    links: [{ joint: "revolute" as const, a: 0.5, alpha: 0, d: 0, theta: 0 }, { joint: "revolute" as const, a: 0.3, alpha: 0, d: 0, theta: 0 }],
  };
  const reg = await client.registerRobot(model);
  assert.ok(reg.created && reg.etag);
  const stale = await client.replaceRobot(model, { etag: '"0"' }).catch((e: unknown) => e);
  assert.ok(stale instanceof KinserveError && stale.status === 412 && stale.kind === "precondition-failed");
  const rep = await client.replaceRobot({ ...model, description: "changed" }, { etag: reg.etag });
  assert.ok(!rep.created && rep.etag !== reg.etag);
  assert.equal((await client.getRobot("ts-etag")).etag, rep.etag);
  await client.deleteRobot("ts-etag", { etag: rep.etag });
  const gone = await client.getRobot("ts-etag").catch((e: unknown) => e);
  assert.ok(gone instanceof KinserveError && gone.status === 404);
  const urdf = await client.urdf("puma560");
  const imported = await client.importUrdf({ name: "ts-urdf", urdf, tip_link: "tool" });
  assert.ok(imported.created);
  const q = [0.3, -0.4, 0.6, 0.2, -0.5, 0.7];
  close((await client.fk("ts-urdf", { joints: q })).pose?.matrix ?? [], (await client.fk("puma560", { joints: q })).pose?.matrix ?? [], 1e-9, "urdf");
  await client.deleteRobot("ts-urdf");
});

test("errors are typed from problem+json with field paths", async () => {
  const e = await client.fk("puma560", { joints: [0, 3, 0, 0, 0, 0] }).catch((x: unknown) => x);
  assert.ok(e instanceof KinserveError);
  assert.equal(e.status, 422);
  assert.equal(e.kind, "invalid-input");
  assert.deepEqual(Object.keys(e.fields), ["joints[1]"]);
  const anonymous = new KinserveClient(BASE);
  const denied = await anonymous.deleteRobot("puma560").catch((x: unknown) => x);
  assert.ok(denied instanceof KinserveError && denied.status === 401);
});

test("stream: latest wins, one request in flight, typed errors", async () => {
  const replies: WsReply[] = [];
  const stream = client.stream("planar_2dof", { onReply: (r) => replies.push(r) });
  await stream.opened;
  const ids: number[] = [];
  for (let i = 0; i < 20; i++) {
    ids.push(stream.send({ joints: [i / 20, 0.1] }));
    assert.ok(stream.busy);
  }
  await stream.next();
  const last = await stream.next();
  assert.deepEqual(replies.map((r) => r.id), [ids[0], ids[19]]);
  assert.equal(stream.superseded, 18);
  const want = await client.fk("planar_2dof", { joints: [19 / 20, 0.1] });
  close(last.pose?.matrix ?? [], want.pose?.matrix ?? [], 1e-12, "stream pose");
  stream.send({ joints: [0, 0, 0] });
  const bad = await stream.next();
  const err = replyError(bad);
  assert.ok(err && err.kind === "invalid-input" && "joints" in err.fields);
  stream.close();
});

test("stream: reconnects after the server closes an idle socket", { skip: IDLE_MS <= 0 ? "KINSERVE_STREAM_IDLE_MS not set" : false }, async () => {
  const stream = client.stream("planar_2dof", { reconnectDelayMs: 50 });
  await stream.opened;
  stream.send({ joints: [0.1, 0.1] });
  await stream.next();
  await new Promise((r) => setTimeout(r, IDLE_MS + 500));
  assert.ok(stream.reconnects >= 1, "the server closed the idle socket and the stream reopened it");
  stream.send({ joints: [0.2, 0.1] });
  const reply = await stream.next();
  const want = await client.fk("planar_2dof", { joints: [0.2, 0.1] });
  close(reply.pose?.matrix ?? [], want.pose?.matrix ?? [], 1e-12, "after reconnect");
  stream.close();
});

test("README examples run (this package's and the repository's From TypeScript)", async () => {
  assert.ok(readme.BLOCKS >= 4 && readme.REPO_BLOCKS >= 1, `${readme.BLOCKS} blocks, ${readme.REPO_BLOCKS} from the repository's README`);
  assert.equal(readme.ALL.length, readme.BLOCKS);
  for (const block of readme.ALL) await block(BASE, TOKEN);
});

const PATH_START = [5, -20, 35, 10, 30, -15];

/** The path of the Python suite: a 4 cm leg up, then a waypoint out of reach. */
async function pathBody(): Promise<Body<"ik_path">> {
  const pose = (await client.fk("puma560", { joints: PATH_START, angle_unit: "deg" })).pose;
  assert.ok(pose);
  const [x, y, z] = pose.position;
  return {
    start: PATH_START, angle_unit: "deg", max_step_length: 0.01,
    waypoints: [{ position: [x, y, z + 0.04], quaternion: pose.quaternion }, { position: [2, 0, 0.5], quaternion: pose.quaternion }],
  };
}

test("ikPath: points, fraction, waypoints reached and why it stopped", async () => {
  const body = await pathBody();
  const path: Answer<"ik_path"> = await client.ikPath("puma560", body);
  assert.equal(path.points[0]?.length, 6);
  close(path.points[0] ?? [], PATH_START, 1e-12, "start");
  assert.equal(path.waypoints_reached, 1);
  assert.ok(path.fraction > 0 && path.fraction < 1, `${path.fraction}`);
  const stop = path.stop;
  assert.ok(stop);
  const reason: Schemas["PathStopReason"] = stop.reason;
  assert.ok(["unreachable", "joint_limits", "joint_jump"].includes(reason), reason);
  assert.equal(stop.step, path.points.length);
  assert.equal(stop.waypoint, 1);
  // The first leg ends on the first waypoint (4 steps of 1 cm).
  const leg = await client.fk("puma560", { joints: path.points[4] ?? [], angle_unit: "deg" });
  close(leg.pose?.position ?? [], body.waypoints[0]?.position ?? [], 1e-9, "end of the first leg");
  // A joint step too small for the first step: stops at step 1 saying so.
  const jump = await client.ikPath("puma560", { ...body, waypoints: body.waypoints.slice(0, 1), max_joint_step: 1e-4 });
  assert.equal(jump.stop?.reason, "joint_jump");
  assert.equal(jump.stop?.step, 1);
  assert.equal(jump.points.length, 1);
  assert.equal(jump.fraction, 0);
  const bad = await client.ikPath("puma560", { ...body, max_step_length: 0 }).catch((e: unknown) => e);
  assert.ok(bad instanceof KinserveError && bad.kind === "invalid-input" && "max_step_length" in bad.fields);
});

test("ik with solutions: all: every solution typed, each reaching the target", async () => {
  const q = [20, -30, 45, 10, 50, -20].map((d) => (d * Math.PI) / 180);
  const target = (await client.fk("puma560", { joints: q })).pose;
  assert.ok(target);
  const ik = await client.ik("puma560", { target: { matrix: target.matrix }, solutions: "all", solver: "analytic", max_solutions: 32 });
  const solver: Schemas["IkSolverUsed"] = ik.solver;
  assert.equal(solver, "analytic");
  assert.equal(ik.iterations, 0);
  assert.equal(ik.truncated, false);
  assert.ok(ik.branch && [0, 1].includes(ik.branch.shoulder) && [0, 1].includes(ik.branch.elbow));
  const solutions: Schemas["IkSolutionItem"][] = ik.solutions ?? [];
  assert.ok(solutions.length >= 2, `${solutions.length} solutions`);
  close(solutions[0]?.joints ?? [], ik.joints, 0, "the first is the answer");
  const reached = await client.fkBatch("puma560", { configurations: solutions.map((s) => s.joints), pose_format: "matrix" });
  for (const [i, m] of (reached.matrices ?? []).entries()) close(m, target.matrix.slice(0, 3), 1e-10, `solution ${i}`);
  for (const s of solutions) {
    assert.ok(s.branch !== null && s.branch !== undefined);
    assert.ok(s.position_error < 1e-9 && s.orientation_error < 1e-9 && s.distance >= 0);
  }
  const few = await client.ik("puma560", { target: { matrix: target.matrix }, solutions: "all", max_solutions: 2 });
  assert.equal(few.truncated, true);
  assert.deepEqual(few.solutions?.map((s) => s.joints), solutions.slice(0, 2).map((s) => s.joints));
  const best = await client.ik("puma560", { target: { matrix: target.matrix } });
  assert.equal(best.solutions, undefined);
});

test("stream: an ik_path message is answered with the path", async () => {
  const body = await pathBody();
  const want = await client.ikPath("puma560", body);
  const stream = client.stream("puma560");
  await stream.opened;
  stream.send({ ik_path: body });
  const reply = await stream.next();
  assert.equal(replyError(reply), undefined);
  const path = replyPath(reply);
  assert.ok(path);
  assert.deepEqual(path.points, want.points);
  assert.equal(path.fraction, want.fraction);
  assert.deepEqual(path.stop, want.stop);
  stream.send({ joints: [0.1, 0.2, 0.3, 0.1, 0.2, 0.3] });
  assert.equal(replyPath(await stream.next()), undefined, "an FK reply has no path");
  stream.close();
});

// The client's share of the compute pool held by other requests of this
// address: IK batches of targets out of reach (8 at once: the whole share of
// a server of up to 17 CPUs) whose callers give up after 2.5 s (the server
// then stops them). Resolves once a probe of ours is refused.
async function holdTheShare(): Promise<Promise<unknown>[]> {
  const far = { position: [3.0, 0.0, 0.2] };
  const body = JSON.stringify({ targets: Array(10_000).fill(far), position_only: true, solver: "numeric" });
  const probe = { target: { position: [0.4, 0.1, 0.4] }, position_only: true };
  const deadline = Date.now() + 30_000;
  for (;;) {
    const holds = Array.from({ length: 8 }, () =>
      fetch(`${BASE}/v1/robots/ur5e/ik/batch`, {
        method: "POST",
        headers: { "content-type": "application/json" },
        body,
        signal: AbortSignal.timeout(5000), // the window the test uses, wide enough under parallel test load
      }).then((r) => r.arrayBuffer(), () => undefined),
    );
    await new Promise((resolve) => setTimeout(resolve, 300));
    const r = await fetch(`${BASE}/v1/robots/ur5e/ik`, { method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(probe) });
    await r.arrayBuffer();
    if (r.status === 503) return holds;
    await Promise.all(holds); // not started yet, or refused by a probe: again
    assert.ok(Date.now() < deadline, "the holds never took the share");
  }
}

test("a request refused before doing anything is sent again after Retry-After; retries: 0 throws it", async () => {
  const body = { target: { position: [0.4, 0.1, 0.4] }, position_only: true };
  let holds = await holdTheShare();
  const eager = new KinserveClient(BASE, { retries: 0 });
  const refused = await eager.ik("ur5e", body).then(
    () => undefined,
    (e: unknown) => e,
  );
  assert.ok(refused instanceof KinserveError, String(refused));
  assert.ok(refused.refused && refused.kind === "overloaded" && refused.status === 503, refused.detail);
  assert.equal(refused.retryAfter, 1);
  assert.match(refused.detail, /holds .*--client-share-percent/);
  await Promise.all(holds);

  // The patient client's attempts are recorded by its fetch, so the test
  // reads what it sent and when instead of timing the whole call. Holds the
  // server finished before the first attempt arrived (a loaded machine) are
  // not what this checks: hold again, a few times at most.
  for (let round = 0; ; round += 1) {
    holds = await holdTheShare();
    const attempts: { status: number; at: number }[] = [];
    const counting: typeof fetch = async (input, init) => {
      const response = await fetch(input, init);
      attempts.push({ status: response.status, at: Date.now() });
      return response;
    };
    const patient = new KinserveClient(BASE, { retries: 10, fetch: counting });
    const answer = await patient.ik("ur5e", body);
    await Promise.all(holds);
    assert.equal(answer.converged, true);
    assert.equal(attempts.at(-1)?.status, 200, JSON.stringify(attempts));
    if (attempts[0]?.status !== 503) {
      assert.ok(round < 4, "the holds never outlasted the patient request's first attempt");
      continue;
    }
    assert.ok(attempts.length >= 2, JSON.stringify(attempts));
    for (const [i, a] of attempts.slice(0, -1).entries()) {
      assert.equal(a.status, 503, `attempt ${i} was refused, then sent again: ${JSON.stringify(attempts)}`);
      const next = attempts[i + 1];
      assert.ok(next && next.at - a.at >= 900, `attempt ${i + 1} waited Retry-After (1 s): ${JSON.stringify(attempts)}`);
    }
    break;
  }
});
