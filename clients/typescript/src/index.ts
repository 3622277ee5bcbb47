// @kinserve/client: a typed client of kinserve's REST API. Every request and
// answer type comes from src/schema.ts, generated at build time from the
// server's OpenAPI document (clients/openapi.json, checked against the live
// /openapi.json by the tests), so the types cannot drift from the server.
// Runtime: the platform's fetch and WebSocket only.
import type { components, operations } from "./schema.js";
import { KinserveError, isProblem } from "./errors.js";
import { FkStream, type StreamOptions } from "./stream.js";

export { KinserveError, isProblem, type Problem } from "./errors.js";
export { FkStream, replyError, replyPath, type StreamOptions, type WsReply, type WsRequest } from "./stream.js";
export { GENERATED_FROM, canonicalJson } from "./generated-from.js";
export type { components, operations, paths } from "./schema.js";

/** The schemas of the OpenAPI document. */
export type Schemas = components["schemas"];
/** An operation id of the OpenAPI document (`fk`, `ik_batch`, ...). */
export type OperationId = keyof operations;
/** The JSON request body of an operation. */
export type Body<K extends OperationId> = operations[K] extends {
  requestBody?: { content: { "application/json": infer B } };
}
  ? B
  : never;
/** The JSON body of an operation's 200 (or 201) answer. */
export type Answer<K extends OperationId> = operations[K]["responses"] extends infer R
  ? R extends { 200: { content: { "application/json": infer J } } }
    ? J
    : R extends { 201: { content: { "application/json": infer J } } }
      ? J
      : never
  : never;
/** The query parameters of an operation. */
export type Query<K extends OperationId> = NonNullable<operations[K]["parameters"]["query"]>;

/** A model and its entity tag (`"17"`, quotes included). */
export interface Versioned<T> {
  value: T;
  etag: string;
}

/** Options of a client. */
export interface ClientOptions {
  /** The server's API token (registering and deleting need it when the server has one). */
  token?: string;
  /** The fetch implementation (default: the platform's). */
  fetch?: typeof fetch;
  /**
   * How many times a request the server refused before doing anything
   * (`overloaded`: 503 + `Retry-After`; it is busy, or this client holds its
   * share of it) is sent again, after the wait the server asks for (at most
   * 5 s). Default 3; 0 throws the refusal at once.
   */
  retries?: number;
}

/** The longest wait between attempts, whatever the server asks (s). */
const MAX_RETRY_AFTER = 5;

const URDF_IMPORT = "application/vnd.kinserve.urdf-import+json";
const OCTETS = "application/octet-stream";

/** The answer of {@link KinserveClient.fkBatchPacked}. */
export interface PackedPoses {
  /** `matrix` (12 numbers per pose) or `position` (3). */
  poseFormat: "matrix" | "position";
  /** Length unit of the positions (`m`, `mm`), from `Kinserve-Length-Unit`. */
  lengthUnit: string;
  /** Numbers per pose. */
  stride: number;
  /** Every pose's numbers, pose after pose. */
  values: Float64Array;
}

/** Whether this platform stores doubles little-endian (every current one does). */
const LITTLE_ENDIAN = new Uint8Array(new Float64Array([1]).buffer)[7] === 0x3f;

/** Joint values as little-endian float64 bytes (a copy only when they are not already). */
function toLittleEndian(q: Float64Array | readonly number[]): Uint8Array<ArrayBuffer> {
  if (LITTLE_ENDIAN && q instanceof Float64Array && q.buffer instanceof ArrayBuffer) {
    return new Uint8Array(q.buffer, q.byteOffset, q.byteLength);
  }
  const out = new DataView(new ArrayBuffer(q.length * 8));
  for (let i = 0; i < q.length; i += 1) out.setFloat64(i * 8, q[i] ?? NaN, true);
  return new Uint8Array(out.buffer);
}

/** Little-endian float64 bytes as numbers. */
function fromLittleEndian(bytes: ArrayBuffer): Float64Array {
  if (bytes.byteLength % 8 !== 0) throw new Error(`${bytes.byteLength} bytes is not a whole number of float64`);
  if (LITTLE_ENDIAN) return new Float64Array(bytes);
  const view = new DataView(bytes);
  return Float64Array.from({ length: bytes.byteLength / 8 }, (_, i) => view.getFloat64(i * 8, true));
}

/** A client of one kinserve server (`new KinserveClient("http://127.0.0.1:8080")`). */
export class KinserveClient {
  readonly baseUrl: string;
  private readonly token: string | undefined;
  private readonly fetchImpl: typeof fetch;
  private readonly retries: number;

  constructor(baseUrl: string, options: ClientOptions = {}) {
    this.baseUrl = baseUrl.replace(/\/+$/, "");
    this.token = options.token;
    this.fetchImpl = options.fetch ?? globalThis.fetch.bind(globalThis);
    this.retries = Math.max(0, Math.floor(options.retries ?? 3));
  }

  private async request(
    method: string,
    path: string,
    init: { body?: unknown; raw?: Uint8Array<ArrayBuffer>; contentType?: string; headers?: Record<string, string> } = {},
  ): Promise<Response> {
    const headers: Record<string, string> = { ...init.headers };
    if (this.token) headers.authorization = `Bearer ${this.token}`;
    let body: string | Uint8Array<ArrayBuffer> | undefined;
    if (init.raw !== undefined) {
      headers["content-type"] = init.contentType ?? OCTETS;
      body = init.raw;
    } else if (init.body !== undefined) {
      headers["content-type"] = init.contentType ?? "application/json";
      body = JSON.stringify(init.body);
    }
    for (let attempt = 0; ; attempt += 1) {
      const response = await this.fetchImpl(this.baseUrl + path, { method, headers, body });
      if (response.ok) return response;
      const error = await errorOf(response);
      if (!error.refused || attempt >= this.retries) throw error;
      const wait = Math.min(Math.max(error.retryAfter ?? 1, 0), MAX_RETRY_AFTER);
      await new Promise((resolve) => setTimeout(resolve, wait * 1000));
    }
  }

  private async json<T>(method: string, path: string, body?: unknown): Promise<T> {
    return (await (await this.request(method, path, { body })).json()) as T;
  }

  /** `GET /v1/robots`: one page. */
  listRobots(query: Query<"list_robots"> = {}): Promise<Answer<"list_robots">> {
    const q = new URLSearchParams();
    if (query.page_size !== undefined && query.page_size !== null) q.set("page_size", String(query.page_size));
    if (query.page_token) q.set("page_token", query.page_token);
    const s = q.toString();
    return this.json("GET", `/v1/robots${s ? `?${s}` : ""}`);
  }

  /** Every robot, sorted by name, fetched a page at a time as the iteration goes on. */
  async *robots(pageSize?: number): AsyncGenerator<Schemas["RobotSummaryDto"]> {
    let token: string | undefined;
    do {
      const page = await this.listRobots({ page_size: pageSize, page_token: token });
      yield* page.robots;
      token = page.next_page_token ?? undefined;
    } while (token);
  }

  /** `GET /v1/robots/{name}`: the model and its ETag. */
  async getRobot(name: string): Promise<Versioned<Answer<"get_robot">>> {
    const r = await this.request("GET", robotPath(name));
    return { value: (await r.json()) as Answer<"get_robot">, etag: r.headers.get("etag") ?? "" };
  }

  /** `POST /v1/robots`: registers a model; 409 if the name is taken. */
  async registerRobot(model: Body<"create_robot">): Promise<Versioned<Answer<"create_robot">> & { created: boolean }> {
    return this.written(await this.request("POST", "/v1/robots", { body: model }));
  }

  /** `PUT /v1/robots/{name}`: registers or replaces; with `etag`, only that version (412 otherwise). */
  async replaceRobot(model: Body<"put_robot">, options: { etag?: string } = {}): Promise<Versioned<Answer<"put_robot">> & { created: boolean }> {
    const headers: Record<string, string> = options.etag ? { "if-match": options.etag } : {};
    return this.written(await this.request("PUT", robotPath(model.name), { body: model, headers }));
  }

  /** Registers (or with `replace`, replaces) a robot from a URDF chain. */
  async importUrdf(body: Schemas["UrdfImportBody"], options: { replace?: boolean; etag?: string } = {}): Promise<Versioned<Answer<"create_robot">> & { created: boolean }> {
    const headers: Record<string, string> = options.etag ? { "if-match": options.etag } : {};
    const [method, path] = options.replace ? ["PUT", robotPath(body.name)] : ["POST", "/v1/robots"];
    return this.written(await this.request(method, path, { body, contentType: URDF_IMPORT, headers }));
  }

  private async written(r: Response): Promise<Versioned<Answer<"create_robot">> & { created: boolean }> {
    return { value: (await r.json()) as Answer<"create_robot">, etag: r.headers.get("etag") ?? "", created: r.status === 201 };
  }

  /** `DELETE /v1/robots/{name}`; with `etag`, only that version (412 otherwise). */
  async deleteRobot(name: string, options: { etag?: string } = {}): Promise<void> {
    await this.request("DELETE", robotPath(name), { headers: options.etag ? { "if-match": options.etag } : {} });
  }

  /** `POST /v1/robots/{name}/fk`. */
  fk(name: string, body: Body<"fk">): Promise<Answer<"fk">> {
    return this.json("POST", robotPath(name, "/fk"), body);
  }

  /** `POST /v1/robots/{name}/fk/batch`. */
  fkBatch(name: string, body: Body<"fk_batch">): Promise<Answer<"fk_batch">> {
    return this.json("POST", robotPath(name, "/fk/batch"), body);
  }

  /**
   * `POST /v1/robots/{name}/fk/batch` packed both ways
   * (`application/octet-stream`, little-endian float64): `q` holds n × dof
   * joint values, configuration after configuration (a `Float64Array` is sent
   * as it is); the options are query parameters (give `joint_count`, the
   * values per configuration: an array of the wrong width is then refused). The answer's `values` hold
   * `stride` numbers per pose: 12 for `matrix` (the top three rows of the 4×4
   * matrix, row-major; `full` is answered as `matrix`), 3 for `position`.
   * The same doubles as `fkBatch`'s JSON, without printing or parsing them.
   */
  async fkBatchPacked(name: string, q: Float64Array | readonly number[], query: Query<"fk_batch"> = {}): Promise<PackedPoses> {
    const params = new URLSearchParams();
    for (const [key, value] of Object.entries(query)) {
      if (value !== undefined && value !== null) params.set(key, String(value));
    }
    const s = params.toString();
    const r = await this.request("POST", robotPath(name, "/fk/batch") + (s ? `?${s}` : ""), {
      raw: toLittleEndian(q),
      headers: { accept: OCTETS },
    });
    const poseFormat = r.headers.get("kinserve-pose-format") === "position" ? "position" : "matrix";
    return {
      poseFormat,
      lengthUnit: r.headers.get("kinserve-length-unit") ?? "",
      stride: poseFormat === "position" ? 3 : 12,
      values: fromLittleEndian(await r.arrayBuffer()),
    };
  }

  /** `POST /v1/robots/{name}/jacobian`. */
  jacobian(name: string, body: Body<"jacobian">): Promise<Answer<"jacobian">> {
    return this.json("POST", robotPath(name, "/jacobian"), body);
  }

  /** `POST /v1/robots/{name}/jacobian/batch`. */
  jacobianBatch(name: string, body: Body<"jacobian_batch">): Promise<Answer<"jacobian_batch">> {
    return this.json("POST", robotPath(name, "/jacobian/batch"), body);
  }

  /** `POST /v1/robots/{name}/ik` (a target not reached is a 422 `ik-not-converged`). */
  ik(name: string, body: Body<"ik">): Promise<Answer<"ik">> {
    return this.json("POST", robotPath(name, "/ik"), body);
  }

  /** `POST /v1/robots/{name}/ik/batch`. */
  ikBatch(name: string, body: Body<"ik_batch">): Promise<Answer<"ik_batch">> {
    return this.json("POST", robotPath(name, "/ik/batch"), body);
  }

  /** `POST /v1/robots/{name}/ik/path`: a Cartesian path from `start` through waypoints (a stopped path is an answer with `stop`). */
  ikPath(name: string, body: Body<"ik_path">): Promise<Answer<"ik_path">> {
    return this.json("POST", robotPath(name, "/ik/path"), body);
  }

  /** `POST /v1/robots/{name}/link-transforms`. */
  linkTransforms(name: string, body: Body<"link_transforms">): Promise<Answer<"link_transforms">> {
    return this.json("POST", robotPath(name, "/link-transforms"), body);
  }

  /** `GET /v1/robots/{name}/closed-form`. */
  closedForm(name: string): Promise<Answer<"closed_form">> {
    return this.json("GET", robotPath(name, "/closed-form"));
  }

  /** `GET /v1/robots/{name}/urdf`: the URDF document. */
  async urdf(name: string): Promise<string> {
    return (await this.request("GET", robotPath(name, "/urdf"))).text();
  }

  /** `GET /healthz`. */
  async healthz(): Promise<string> {
    return (await this.request("GET", "/healthz")).text();
  }

  /** `GET /readyz`. */
  readyz(): Promise<Answer<"readyz">> {
    return this.json("GET", "/readyz");
  }

  /** `GET /metrics` (Prometheus text). */
  async metrics(): Promise<string> {
    return (await this.request("GET", "/metrics")).text();
  }

  /** `GET /openapi.json`. */
  openapi(): Promise<unknown> {
    return this.json("GET", "/openapi.json");
  }

  /** `GET /v1/robots/{name}/fk/stream`: a latest-wins WebSocket stream with reconnect. */
  stream(name: string, options: StreamOptions = {}): FkStream {
    const url = this.baseUrl.replace(/^http/, "ws") + robotPath(name, "/fk/stream");
    return new FkStream(url, options);
  }
}

/** The client method of every operation of the OpenAPI document: tsc fails
 * here when the server gains (or loses) an operation the client lacks. */
export const OPERATIONS: { readonly [K in OperationId]: keyof KinserveClient } = {
  healthz: "healthz",
  metrics_text: "metrics",
  readyz: "readyz",
  list_robots: "listRobots",
  create_robot: "registerRobot",
  get_robot: "getRobot",
  put_robot: "replaceRobot",
  delete_robot: "deleteRobot",
  closed_form: "closedForm",
  fk: "fk",
  fk_batch: "fkBatch",
  stream: "stream",
  ik: "ik",
  ik_batch: "ikBatch",
  ik_path: "ikPath",
  jacobian: "jacobian",
  jacobian_batch: "jacobianBatch",
  link_transforms: "linkTransforms",
  urdf: "urdf",
};

function robotPath(name: string, tail = ""): string {
  return `/v1/robots/${encodeURIComponent(name)}${tail}`;
}

async function errorOf(response: Response): Promise<KinserveError> {
  const text = await response.text();
  let body: unknown;
  try {
    body = JSON.parse(text);
  } catch {
    body = undefined;
  }
  const retryAfter = Number(response.headers.get("retry-after") ?? Number.NaN);
  if (isProblem(body)) return new KinserveError(body, Number.isFinite(retryAfter) ? retryAfter : undefined);
  return new KinserveError({
    type: "about:blank",
    title: response.statusText,
    status: response.status,
    detail: text || response.statusText,
  });
}
