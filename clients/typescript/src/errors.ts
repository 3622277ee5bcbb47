// Errors: one class, KinserveError, built from the server's
// application/problem+json answers (REST and WebSocket replies alike).
import type { components } from "./schema.js";

/** RFC 9457 problem details as the server writes them. */
export type Problem = components["schemas"]["Problem"];

/** An error answer of the server. */
export class KinserveError extends Error {
  /** Problem type URI (`urn:kinserve:problem:invalid-input`). */
  readonly type: string;
  /** HTTP status. */
  readonly status: number;
  /** Short summary of the problem type. */
  readonly title: string;
  /** Explanation of this occurrence. */
  readonly detail: string;
  /** Field path -> message (`{"joints[1]": "..."}`), from the problem's `errors`. */
  readonly fields: Record<string, string>;
  /** The problem document itself (with `best_attempt` for `ik-not-converged`). */
  readonly problem: Problem;
  /** Seconds the server asked to wait before trying again (`Retry-After`), when it said. */
  readonly retryAfter: number | undefined;

  constructor(problem: Problem, retryAfter?: number) {
    super(problem.detail);
    this.name = "KinserveError";
    this.type = problem.type;
    this.status = problem.status;
    this.title = problem.title;
    this.detail = problem.detail;
    this.fields = Object.fromEntries((problem.errors ?? []).map((e) => [e.field, e.message]));
    this.problem = problem;
    this.retryAfter = retryAfter;
  }

  /**
   * Whether the server refused the request before doing anything
   * (`overloaded`: a budget spent, or this client holding its share of it),
   * so that sending it again is safe whatever it asks.
   */
  get refused(): boolean {
    return this.kind === "overloaded";
  }

  /** The problem kind: the end of `type` (`invalid-input`, `not-found`, ...). */
  get kind(): string {
    return this.type.replace(/^urn:kinserve:problem:/, "");
  }
}

/** Whether a parsed JSON value is a problem document. */
export function isProblem(value: unknown): value is Problem {
  return typeof value === "object" && value !== null && "type" in value && "status" in value && "detail" in value;
}
