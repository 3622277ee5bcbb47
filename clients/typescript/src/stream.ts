// The WebSocket stream helper: FK / Jacobian / IK / Cartesian path requests on
// /v1/robots/{name}/fk/stream with at most one request in flight; a send
// while one is in flight replaces the unsent one, which goes out when the
// reply comes (latest wins: what a UI following a slider wants). Reconnects
// when the socket closes and resends the request that was in flight.
import type { components } from "./schema.js";
import { KinserveError } from "./errors.js";

/** A stream request (without `id`: the stream numbers them). */
export type WsRequest = Omit<components["schemas"]["WsRequest"], "id">;
/** A stream reply (`error` holds a problem document when the request failed). */
export type WsReply = components["schemas"]["WsReply"] & { id: number; error?: components["schemas"]["Problem"] | null };

/** Options of a stream. */
export interface StreamOptions {
  /** Reconnect when the socket closes (default true). */
  reconnect?: boolean;
  /** Wait before reconnecting, ms (default 200). */
  reconnectDelayMs?: number;
  /** Called with every reply, in order. */
  onReply?: (reply: WsReply) => void;
  /** The WebSocket constructor (default: the platform's `WebSocket`). */
  WebSocket?: typeof WebSocket;
}

/** The path of a reply to an `ik_path` request (points, fraction,
 * waypoints reached, stop), or undefined for any other reply. */
export function replyPath(reply: WsReply): components["schemas"]["WsIkPath"] | undefined {
  if (reply.error || !Array.isArray((reply as Partial<WsReply>).points)) return undefined;
  return { points: reply.points, fraction: reply.fraction, waypoints_reached: reply.waypoints_reached, stop: reply.stop ?? null };
}

/** The error of a failed reply, or undefined. */
export function replyError(reply: WsReply): KinserveError | undefined {
  return reply.error ? new KinserveError(reply.error) : undefined;
}

/** An open FK stream (from `KinserveClient.stream`). */
export class FkStream {
  readonly url: string;
  /** Requests sent (retransmissions after a reconnect not counted). */
  sent = 0;
  /** Requests replaced by a newer one before they went out. */
  superseded = 0;
  /** Times the socket was reopened. */
  reconnects = 0;
  private ws: WebSocket | undefined;
  private inFlight: (WsRequest & { id: number }) | undefined;
  private pending: (WsRequest & { id: number }) | undefined;
  private nextId = 1;
  private closed = false;
  private readonly waiters: ((reply: WsReply) => void)[] = [];
  private readonly options: Required<Omit<StreamOptions, "onReply">> & Pick<StreamOptions, "onReply">;
  private openedResolve: (() => void) | undefined;
  /** Resolves when the socket first opens. */
  readonly opened: Promise<void>;

  constructor(url: string, options: StreamOptions = {}) {
    this.url = url;
    this.options = {
      reconnect: options.reconnect ?? true,
      reconnectDelayMs: options.reconnectDelayMs ?? 200,
      onReply: options.onReply,
      WebSocket: options.WebSocket ?? globalThis.WebSocket,
    };
    this.opened = new Promise((resolve) => (this.openedResolve = resolve));
    this.connect();
  }

  /** Queues a request; returns its id. Goes out now if nothing is in flight,
   * else when the reply comes, unless a newer send replaces it first. */
  send(request: WsRequest): number {
    const message = { ...request, id: this.nextId++ };
    if (this.inFlight || !this.isOpen()) {
      if (this.pending) this.superseded++;
      this.pending = message;
    } else {
      this.transmit(message);
    }
    return message.id;
  }

  /** The next reply. */
  next(): Promise<WsReply> {
    return new Promise((resolve) => this.waiters.push(resolve));
  }

  /** Whether a request is waiting for its reply. */
  get busy(): boolean {
    return this.inFlight !== undefined;
  }

  /** Closes the socket for good. */
  close(): void {
    this.closed = true;
    this.ws?.close();
  }

  private isOpen(): boolean {
    return this.ws !== undefined && this.ws.readyState === this.options.WebSocket.OPEN;
  }

  private transmit(message: WsRequest & { id: number }, resend = false): void {
    this.inFlight = message;
    if (!resend) this.sent++;
    this.ws?.send(JSON.stringify(message));
  }

  private connect(): void {
    const ws = new this.options.WebSocket(this.url);
    this.ws = ws;
    ws.onopen = () => {
      this.openedResolve?.();
      if (this.inFlight) this.transmit(this.inFlight, true);
      else this.flush();
    };
    ws.onmessage = (event: MessageEvent) => this.receive(JSON.parse(String(event.data)) as WsReply);
    ws.onclose = () => {
      if (this.closed || !this.options.reconnect) return;
      this.reconnects++;
      setTimeout(() => this.connect(), this.options.reconnectDelayMs);
    };
  }

  private receive(reply: WsReply): void {
    if (this.inFlight && reply.id === this.inFlight.id) this.inFlight = undefined;
    this.options.onReply?.(reply);
    this.waiters.shift()?.(reply);
    this.flush();
  }

  private flush(): void {
    if (!this.inFlight && this.pending && this.isOpen()) {
      const next = this.pending;
      this.pending = undefined;
      this.transmit(next);
    }
  }
}
