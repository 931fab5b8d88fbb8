// The server connection: the cut stream over a WebSocket, and the cluster
// geometry cache.
//
// One request is in flight at a time and only the newest view waits behind
// it: when views change faster than answers come (playing, dragging), the
// stale ones are dropped instead of queueing, so the drawn cut lags the view
// by at most one round trip. The connection comes back by itself after the
// server restarts; its first answer then has `reset` set.

import { glbReady, parseGlb } from "./glb.js";

export class CutConnection {
  // handlers: message(msg, request, millis) -> Promise, status(text|null)
  constructor(url, handlers) {
    this.url = url;
    this.handlers = handlers;
    this.pending = null;
    this.inFlight = null;
    this.retry = 500;
    this.socket = null;
    this.last = null;
  }

  open() {
    const ws = new WebSocket(this.url);
    this.socket = ws;
    ws.onopen = () => {
      this.retry = 500;
      this.handlers.status(null);
      // A new stream (after a restart, or another replica behind a load
      // balancer) knows nothing of this viewer: the last view goes again,
      // so the cut comes back without waiting for the view to move.
      if (!this.pending && this.last) this.pending = this.last;
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
    this.last = this.pending;
    this.pending = null;
    ws.send(JSON.stringify(this.inFlight.body));
  }

  busy() {
    return !!(this.inFlight || this.pending);
  }
}

// At most MAX_LOADS geometry requests are in flight and the rest wait in
// the page: a browser refuses fetches ("Failed to fetch") when a cut brings
// a thousand or more at once, and one origin serves six at a time over
// HTTP/1.1 anyway. A request that fails is tried again after each of
// RETRY_MS in turn before the load fails; an answer that will not change
// (a 4xx but 408 and 429, or a GLB that does not parse) is not retried.
const MAX_LOADS = 8;
const RETRY_MS = [250, 1000, 4000];

// The GLBs asked for in one turn of the page (one cut's additions) go in
// batches of at most BATCH (the server's bound) through the batch endpoint
// (`.../geometry?h=HASH,...`, docs/api.md): a cut of 2,000 new clusters is
// 20 requests, not 2,000. Each batch lists its hashes sorted, so the same
// set is the same URL, cached like a single GLB.
const BATCH = 100;

class Permanent extends Error {}

async function fetchBuffer(url) {
  const r = await fetch(url);
  if (!r.ok) {
    const message = `${url}: HTTP ${r.status}`;
    const again = r.status >= 500 || r.status === 408 || r.status === 429;
    throw again ? new Error(message) : new Permanent(message);
  }
  return r.arrayBuffer();
}

// A batch body: a little-endian u32 length, a JSON index of that length
// ({files: [{hash, offset, length}]}), the GLBs -> Map hash -> ArrayBuffer.
function unpackBatch(url, body) {
  const dv = new DataView(body);
  const n = body.byteLength >= 4 ? dv.getUint32(0, true) : -1;
  if (n < 0 || 4 + n > body.byteLength) throw new Permanent(`${url}: not a geometry batch`);
  const index = JSON.parse(new TextDecoder().decode(new Uint8Array(body, 4, n)));
  const files = new Map();
  for (const f of index.files || []) {
    if (f.offset + f.length > body.byteLength) throw new Permanent(`${url}: ${f.hash} runs past the body`);
    files.set(f.hash, body.slice(f.offset, f.offset + f.length));
  }
  return files;
}

// `/api/v1/scenes/S/geometry/HASH.glb` -> [".../geometry", HASH], or null.
function splitGeometryUrl(url) {
  const m = /^(.*\/geometry)\/([0-9a-f]{64})\.glb$/.exec(url);
  return m ? [m[1], m[2]] : null;
}

// The GPU memory the cache keeps beyond what the drawn cut uses: past it,
// the geometry and textures the cut dropped longest ago are freed.
const GPU_BUDGET = 512 * 1024 * 1024;

// GLBs are content-addressed (the hash is in the URL): each is fetched and
// uploaded once and kept while the GPU memory allows (evict()). A cluster's
// baked colour texture, a PNG in its GLB, is decoded by the browser.
export class GeometryCache {
  // encoding: null for the stored (compact) GLBs, or "plain".
  constructor(renderer, encoding = null) {
    this.renderer = renderer;
    this.encoding = encoding;
    this.entries = new Map();
    // url -> what upload() made, in the order last used.
    this.uploaded = new Map();
    this.gpuBytes = 0;
    this.freed = 0;
    this.bytes = 0;
    this.textureBytes = 0;
    this.files = 0;
    this.loading = 0;
    // Requests in flight, the most at once, and failed attempts tried again.
    this.active = 0;
    this.peak = 0;
    this.retries = 0;
    // Geometry requests made (a batch counts once).
    this.requests = 0;
    this.queue = [];
    // {url, resolve, reject} waiting for the next batch.
    this.wanted = [];
  }

  get(url) {
    let entry = this.entries.get(url);
    if (!entry) {
      this.loading++;
      entry = this.fetchBatched(url)
        .then(async (buffer) => {
          let mesh;
          let image = null;
          try {
            await glbReady;
            mesh = parseGlb(buffer);
            if (mesh.image) {
              image = await createImageBitmap(new Blob([mesh.image.bytes], { type: mesh.image.type }), {
                colorSpaceConversion: "none",
                premultiplyAlpha: "none",
              });
            }
          } catch (e) {
            throw new Error(`${url}: ${e.message}`);
          }
          this.bytes += buffer.byteLength;
          if (mesh.image) this.textureBytes += mesh.image.bytes.byteLength;
          this.files++;
          const gpu = this.renderer.upload(mesh, image);
          if (image) image.close();
          gpu.fileBytes = buffer.byteLength;
          gpu.textureFileBytes = mesh.image ? mesh.image.bytes.byteLength : 0;
          this.uploaded.set(url, gpu);
          this.gpuBytes += gpu.bytes;
          return gpu;
        })
        .catch((e) => {
          // A failed load can be asked for again (the page retries the
          // clusters it misses).
          this.entries.delete(url);
          throw e;
        })
        .finally(() => this.loading--);
      this.entries.set(url, entry);
    }
    return entry;
  }

  // Frees the geometry not in `inUse` (a Set of URLs the drawn cut holds),
  // least recently used first, while the GPU holds more than the budget.
  evict(inUse) {
    for (const url of inUse) {
      const gpu = this.uploaded.get(url);
      if (!gpu) continue;
      this.uploaded.delete(url);
      this.uploaded.set(url, gpu);
    }
    for (const [url, gpu] of this.uploaded) {
      if (this.gpuBytes <= GPU_BUDGET) break;
      if (inUse.has(url)) continue;
      this.renderer.free(gpu);
      this.uploaded.delete(url);
      this.entries.delete(url);
      this.gpuBytes -= gpu.bytes;
      this.freed++;
    }
  }

  // The GLB at `url`, fetched in the next batch of its scene.
  fetchBatched(url) {
    if (!splitGeometryUrl(url)) return this.fetchRetrying(url);
    return new Promise((resolve, reject) => {
      this.wanted.push({ url, resolve, reject });
      // Every get() of this turn joins the same batches.
      if (this.wanted.length === 1) setTimeout(() => this.sendBatches(), 0);
    });
  }

  sendBatches() {
    const wanted = this.wanted;
    this.wanted = [];
    const byBase = new Map();
    for (const w of wanted) {
      const [base, hash] = splitGeometryUrl(w.url);
      if (!byBase.has(base)) byBase.set(base, []);
      byBase.get(base).push({ ...w, hash });
    }
    for (const [base, items] of byBase) {
      items.sort((a, b) => (a.hash < b.hash ? -1 : a.hash > b.hash ? 1 : 0));
      // Even batches: 101 GLBs are two of 51 and 50, not 100 and 1.
      const count = Math.ceil(items.length / BATCH);
      const size = Math.ceil(items.length / count);
      for (let i = 0; i < items.length; i += size) this.loadBatch(base, items.slice(i, i + size));
    }
  }

  async loadBatch(base, items) {
    const encoding = this.encoding ? `&encoding=${this.encoding}` : "";
    const url = `${base}?h=${items.map((w) => w.hash).join(",")}${encoding}`;
    let files;
    try {
      files = unpackBatch(url, await this.fetchRetrying(url));
    } catch (e) {
      // A batch the server refuses for good (a hash it no longer has,
      // after a rebuild) goes again one GLB at a time, so that only the
      // missing ones fail.
      if (e instanceof Permanent && items.length > 1) {
        const query = this.encoding ? `?encoding=${this.encoding}` : "";
        for (const w of items) this.fetchRetrying(`${w.url}${query}`).then(w.resolve, w.reject);
      } else {
        for (const w of items) w.reject(e);
      }
      return;
    }
    for (const w of items) {
      const file = files.get(w.hash);
      if (file) w.resolve(file);
      else w.reject(new Permanent(`${url}: no ${w.hash} in the answer`));
    }
  }

  async fetchRetrying(url) {
    for (let attempt = 0; ; attempt++) {
      try {
        return await this.limited(() => {
          this.requests++;
          return fetchBuffer(url);
        });
      } catch (e) {
        if (e instanceof Permanent || attempt >= RETRY_MS.length) throw e;
        this.retries++;
        await new Promise((r) => setTimeout(r, RETRY_MS[attempt]));
      }
    }
  }

  // job() started once fewer than MAX_LOADS are in flight, in call order.
  limited(job) {
    return new Promise((resolve, reject) => {
      this.queue.push({ job, resolve, reject });
      this.pump();
    });
  }

  pump() {
    while (this.active < MAX_LOADS && this.queue.length > 0) {
      const { job, resolve, reject } = this.queue.shift();
      this.active++;
      this.peak = Math.max(this.peak, this.active);
      job()
        .then(resolve, reject)
        .finally(() => {
          this.active--;
          this.pump();
        });
    }
  }
}
