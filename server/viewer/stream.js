// The server connection: the cut stream over a WebSocket, and the cluster
// geometry cache.
//
// One request is in flight at a time and only the newest view waits behind
// it: when views change faster than answers come (playing, dragging), the
// stale ones are dropped instead of queueing, so the drawn cut lags the view
// by at most one round trip. The connection comes back by itself after the
// server restarts; its first answer then has `reset` set.

import { parseGlb } from "./glb.js";

export class CutConnection {
  // handlers: message(msg, request, millis) -> Promise, status(text|null)
  constructor(url, handlers) {
    this.url = url;
    this.handlers = handlers;
    this.pending = null;
    this.inFlight = null;
    this.retry = 500;
    this.socket = null;
  }

  open() {
    const ws = new WebSocket(this.url);
    this.socket = ws;
    ws.onopen = () => {
      this.retry = 500;
      this.handlers.status(null);
      this.flush();
    };
    ws.onmessage = async (event) => {
      const sent = this.inFlight;
      const millis = sent ? performance.now() - sent.at : 0;
      let msg;
      try {
        msg = JSON.parse(event.data);
      } catch (e) {
        msg = { error: { message: `unreadable answer from the server: ${e.message}` } };
      }
      try {
        await this.handlers.message(msg, sent && sent.body, millis);
      } finally {
        this.inFlight = null;
        this.flush();
      }
    };
    ws.onclose = () => {
      if (this.socket !== ws) return;
      // The view that was in flight is asked again on the next connection.
      if (this.inFlight && !this.pending) this.pending = this.inFlight.body;
      this.inFlight = null;
      this.handlers.status(`Lost the connection to the server at ${location.host}; retrying in ${(this.retry / 1000).toFixed(1)} s.`);
      setTimeout(() => this.open(), this.retry);
      this.retry = Math.min(this.retry * 2, 8000);
    };
  }

  request(body) {
    this.pending = body;
    this.flush();
  }

  flush() {
    const ws = this.socket;
    if (!ws || ws.readyState !== WebSocket.OPEN || this.inFlight || !this.pending) return;
    this.inFlight = { body: this.pending, at: performance.now() };
    this.pending = null;
    ws.send(JSON.stringify(this.inFlight.body));
  }

  busy() {
    return !!(this.inFlight || this.pending);
  }
}

// GLBs are content-addressed (the hash is in the URL): each is fetched and
// uploaded once and kept for the session.
export class GeometryCache {
  constructor(renderer) {
    this.renderer = renderer;
    this.entries = new Map();
    this.bytes = 0;
    this.files = 0;
    this.loading = 0;
  }

  get(url) {
    let entry = this.entries.get(url);
    if (!entry) {
      this.loading++;
      entry = fetch(url)
        .then((r) => {
          if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
          return r.arrayBuffer();
        })
        .then((buffer) => {
          let mesh;
          try {
            mesh = parseGlb(buffer);
          } catch (e) {
            throw new Error(`${url}: ${e.message}`);
          }
          this.bytes += buffer.byteLength;
          this.files++;
          return this.renderer.upload(mesh);
        })
        .catch((e) => {
          // A failed load is tried again the next time the cut needs it.
          this.entries.delete(url);
          throw e;
        })
        .finally(() => this.loading--);
      this.entries.set(url, entry);
    }
    return entry;
  }
}
