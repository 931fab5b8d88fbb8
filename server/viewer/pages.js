// Shared vertex buffers ("pages") for draw-call batching. A cut of the
// paper scene draws a thousand or more clusters of a few dozen triangles
// each; one draw call apiece makes the calls themselves (each validated
// by WebGL, and queued to the GPU process) what a frame costs. So the
// clusters that need nothing of their own to be drawn (no transform, no
// joints, no texture: the static and pseudo-dynamic ones) keep their
// vertices in a page, and the renderer draws all of a page's drawn
// clusters with one call over an index buffer of their triangles, built
// again only when the set drawn from that page changes.
//
// A page holds PAGE_VERTICES vertices (a larger mesh gets a page of its
// own); a mesh takes a contiguous range, found first-fit in the page's
// free ranges, and gives it back when the cache frees it. A page with
// nothing in it is deleted.
//
// Per vertex: position (3 floats), normal (3 floats, zero where the mesh
// has none: the shader then lights the face), colour (4 floats, the
// renderer's default grey where the mesh has none) and feature id.
export const PAGE_VERTICES = 1 << 19;
const FLOATS = [3, 3, 4, 1];
export const PAGE_VERTEX_BYTES = 4 * FLOATS.reduce((a, b) => a + b, 0);

// The colour of a mesh without vertex colours, in a page or not.
export const DEFAULT_COLOUR = [0.75, 0.75, 0.75, 1];

class Page {
  constructor(gl, capacity) {
    this.capacity = capacity;
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    this.buffers = FLOATS.map((size, location) => {
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, 4 * size * capacity, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, size, gl.FLOAT, false, 0, 0);
      return b;
    });
    // The triangles of the clusters last drawn from the page, and which.
    this.drawn = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.drawn);
    gl.bindVertexArray(null);
    this.drawnOf = [];
    this.drawnCount = 0;
    // Free ranges [first, count], by first, none adjacent.
    this.free = [[0, capacity]];
    this.used = 0;
  }
}

export class Pages {
  constructor(gl) {
    this.gl = gl;
    this.pages = [];
  }

  // Places a mesh with feature ids (glb.js's parse) in a page:
  // {page, first, count, indices (its triangles' indices into the page)}.
  place(mesh) {
    const gl = this.gl;
    const n = mesh.positions.length / 3;
    let page = null;
    let at = -1;
    for (const p of this.pages) {
      at = p.free.findIndex(([, count]) => count >= n);
      if (at >= 0) {
        page = p;
        break;
      }
    }
    if (!page) {
      page = new Page(gl, Math.max(PAGE_VERTICES, n));
      this.pages.push(page);
      at = 0;
    }
    const range = page.free[at];
    const first = range[0];
    if (range[1] === n) page.free.splice(at, 1);
    else page.free[at] = [first + n, range[1] - n];
    page.used += n;

    const normals = mesh.normals || new Float32Array(3 * n);
    let colors = mesh.colors;
    if (!colors) {
      colors = new Float32Array(4 * n);
      for (let i = 0; i < n; i++) colors.set(DEFAULT_COLOUR, 4 * i);
    }
    [mesh.positions, normals, colors, mesh.features].forEach((data, i) => {
      gl.bindBuffer(gl.ARRAY_BUFFER, page.buffers[i]);
      gl.bufferSubData(gl.ARRAY_BUFFER, 4 * FLOATS[i] * first, data);
    });
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    const indices = new Uint32Array(mesh.indices.length);
    for (let i = 0; i < indices.length; i++) indices[i] = mesh.indices[i] + first;
    return { page, first, count: n, indices };
  }

  // Gives a placed range back; a page left empty is deleted.
  release(slot) {
    const gl = this.gl;
    const { page, first, count } = slot;
    if (slot.own) gl.deleteBuffer(slot.own);
    slot.own = null;
    page.used -= count;
    if (page.used === 0) {
      gl.deleteVertexArray(page.vao);
      for (const b of page.buffers) gl.deleteBuffer(b);
      gl.deleteBuffer(page.drawn);
      this.pages.splice(this.pages.indexOf(page), 1);
      return;
    }
    const free = page.free;
    let at = free.findIndex(([f]) => f > first);
    if (at < 0) at = free.length;
    free.splice(at, 0, [first, count]);
    // Joined with the next range, then with the one before.
    if (at + 1 < free.length && first + count === free[at + 1][0]) {
      free[at][1] += free[at + 1][1];
      free.splice(at + 1, 1);
    }
    if (at > 0 && free[at - 1][0] + free[at - 1][1] === first) {
      free[at - 1][1] += free[at][1];
      free.splice(at, 1);
    }
    // The drawn set is made again at the next draw: a new mesh in this
    // range is a different slot.
    page.drawnOf = [];
  }

  // Binds `page`'s vertex array with the triangles of `slots` (placed in
  // it) as its index buffer, uploaded only when they differ from the last
  // call's; returns the index count.
  bindDrawn(page, slots) {
    const gl = this.gl;
    gl.bindVertexArray(page.vao);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, page.drawn);
    const same = slots.length === page.drawnOf.length && slots.every((s, i) => s === page.drawnOf[i]);
    if (!same) {
      let total = 0;
      for (const s of slots) total += s.indices.length;
      const all = new Uint32Array(total);
      let k = 0;
      for (const s of slots) {
        all.set(s.indices, k);
        k += s.indices.length;
      }
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, all, gl.DYNAMIC_DRAW);
      page.drawnOf = slots;
      page.drawnCount = total;
    }
    return page.drawnCount;
  }

  // Binds `page`'s vertex array with one slot's triangles (its own index
  // buffer, made on first use): a cluster of the page drawn alone.
  bindOne(slot) {
    const gl = this.gl;
    gl.bindVertexArray(slot.page.vao);
    if (!slot.own) {
      slot.own = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, slot.own);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, slot.indices, gl.STATIC_DRAW);
    } else {
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, slot.own);
    }
  }
}
