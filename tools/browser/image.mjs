// What the eye sees of the cut, for `hdlod bench image` (server/src/cmd/bench_image.rs):
//   node tools/browser/image.mjs BASE_URL SCENE WIDTH HEIGHT PIXEL_ERROR OUT_DIR [SUPERSAMPLE [JITTER]]
// renders each cell of table 2 (the start, 1/3, 2/3 and end of the period;
// the camera of the table at 1, 2 and 4 times the distance where the scene
// fills the view) twice in the web viewer: the cut at PIXEL_ERROR, and full
// detail, the cut at a vanishing pixel error, which refines every cluster
// with any error down to the leaves (the original objects). Both pictures
// are kept in OUT_DIR; one JSON object goes to stdout with, per cell, the
// pixels of the scene (off the background in either picture), the share
// of them that differ by more than 16/255 and by more than 48/255 in some
// channel, the PSNR over them, and the triangles, clusters and GLB bytes
// (textures included, and of those) of each, with the cut's cluster ids.
// SUPERSAMPLE n (default 1) renders at n x n device pixels per pixel, the
// pixel error scaled to match (the same cut), and averages each n x n
// block before comparing: more samples per pixel than the GPU's
// multisampling gives, for pixels that show sub-pixel detail. JITTER m
// (default 1) draws each picture m x m times, the projection moved by a
// stratified offset within a device pixel each time, and averages them
// (the viewer's `accumulate`): m^2 times the samples again, so that both
// pictures come close to what they would converge to. Each cell
// also compares full detail with itself moved by one device pixel (1/n of
// a pixel) across: how much of the measure a displacement that small
// makes alone, the floor a cut whose every point is within its error of
// the original cannot be expected to go under.
import { mkdirSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { launch } from "./launch.mjs";
import { BACKGROUND, canvasShot, hook, settle } from "./page.mjs";

const [base, scene, width, height, pixelError, outDir, samples = "1", jitters = "1"] = process.argv.slice(2);
if (!outDir) {
  console.error("usage: node image.mjs BASE_URL SCENE WIDTH HEIGHT PIXEL_ERROR OUT_DIR [SUPERSAMPLE [JITTER]]");
  process.exit(2);
}
const supersample = Number(samples);
const jitter = Number(jitters);
// The centres of an m x m grid over a device pixel, around its centre.
const offsets = [];
for (let b = 0; b < jitter; b++) for (let a = 0; a < jitter; a++) offsets.push([(a + 0.5) / jitter - 0.5, (b + 0.5) / jitter - 0.5]);
mkdirSync(outDir, { recursive: true });
const FULL_DETAIL = 1e-6;
const SCREENS = [["1/1", 1], ["1/4", 2], ["1/16", 4]];
const TIMES = [["start", 0], ["1/3", 1 / 3], ["2/3", 2 / 3], ["end", 1]];
const out = { width: Number(width), height: Number(height), pixelError: Number(pixelError), supersample, jitter, cells: [], errors: [] };

// Two canvas pictures compared over the scene's pixels, decoded by the
// page; each averaged over blocks of n x n device pixels, the second first
// moved `shift` device pixels across (its first columns repeated).
function difference(page, a, b, n, shift = 0) {
  return page.evaluate(async ([da, db, bg, n, shift]) => {
    const load = async (d, shift) => {
      const img = await createImageBitmap(await (await fetch(`data:image/png;base64,${d}`)).blob());
      const c = new OffscreenCanvas(img.width, img.height);
      const g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      const px = g.getImageData(0, 0, img.width, img.height).data;
      const [w, h] = [Math.floor(img.width / n), Math.floor(img.height / n)];
      const mean = new Float64Array(4 * w * h);
      for (let y = 0; y < h * n; y++) {
        for (let x = 0; x < w * n; x++) {
          const from = 4 * (y * img.width + Math.max(0, x - shift));
          const to = 4 * (Math.floor(y / n) * w + Math.floor(x / n));
          for (let k = 0; k < 4; k++) mean[to + k] += px[from + k] / (n * n);
        }
      }
      return mean;
    };
    const [pa, pb] = [await load(da, 0), await load(db, shift)];
    const off = (px, i) => Math.abs(px[i] - bg[0]) + Math.abs(px[i + 1] - bg[1]) + Math.abs(px[i + 2] - bg[2]) > 12;
    let scene = 0;
    let over16 = 0;
    let over48 = 0;
    let squares = 0;
    for (let i = 0; i < pa.length; i += 4) {
      if (!off(pa, i) && !off(pb, i)) continue;
      scene++;
      let worst = 0;
      for (let k = 0; k < 3; k++) {
        const d = Math.abs(pa[i + k] - pb[i + k]);
        worst = Math.max(worst, d);
        squares += d * d;
      }
      if (worst > 16) over16++;
      if (worst > 48) over48++;
    }
    const mse = scene > 0 ? squares / (3 * scene) : 0;
    return { scenePixels: scene, over16, over48, psnr: mse > 0 ? 10 * Math.log10((255 * 255) / mse) : null };
  }, [a.toString("base64"), b.toString("base64"), BACKGROUND, n, shift]);
}

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: out.width, height: out.height }, deviceScaleFactor: supersample });
  page.on("pageerror", (e) => out.errors.push(`page error: ${e.message}`));
  page.on("console", (m) => {
    if (m.type() === "error") out.errors.push(`console: ${m.text()}`);
  });
  // The viewer's pixels are device pixels: n of them to a pixel here.
  const devicePixelError = out.pixelError * supersample;
  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}&pixel_error=${devicePixelError}`);
  const first = await settle(page);
  const render = async (pe, name) => {
    await hook(page, (v, p) => v.setPixelError(p), pe);
    const s = await settle(page);
    const png = jitter > 1 ? Buffer.from(await hook(page, (v, o) => v.accumulate(o), offsets), "base64") : await canvasShot(page);
    writeFileSync(join(outDir, `${name}.png`), png);
    return { png, ids: s.ids, triangles: s.triangles, clusters: s.clusters, leaves: s.leafClusters, bytes: s.cutBytes, textureBytes: s.cutTextureBytes };
  };
  for (const [screen, factor] of SCREENS) {
    for (const [time, fraction] of TIMES) {
      await hook(page, (v, [f, t]) => {
        v.setDistanceFactor(f);
        v.setTime(t);
      }, [factor, first.span * fraction]);
      const tag = `${time.replace("/", "_")}-${screen.replace("/", "_")}`;
      const cut = await render(devicePixelError, `${tag}-cut`);
      const full = await render(FULL_DETAIL, `${tag}-full`);
      const d = await difference(page, cut.png, full.png, supersample);
      const moved = await difference(page, full.png, full.png, supersample, 1);
      out.cells.push({
        time,
        screen,
        cut: { ids: cut.ids, triangles: cut.triangles, clusters: cut.clusters, bytes: cut.bytes, textureBytes: cut.textureBytes },
        full: { triangles: full.triangles, clusters: full.clusters, leaves: full.leaves, bytes: full.bytes, textureBytes: full.textureBytes },
        scenePixels: d.scenePixels,
        share16: d.scenePixels > 0 ? d.over16 / d.scenePixels : 0,
        share48: d.scenePixels > 0 ? d.over48 / d.scenePixels : 0,
        psnr: d.psnr,
        shifted: {
          pixels: 1 / supersample,
          share16: moved.scenePixels > 0 ? moved.over16 / moved.scenePixels : 0,
          share48: moved.scenePixels > 0 ? moved.over48 / moved.scenePixels : 0,
        },
        pictures: [`${tag}-cut.png`, `${tag}-full.png`],
      });
    }
  }
} catch (e) {
  out.errors.push(`driver: ${e.stack || e}`);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
