// A skinned cluster posed by its joints, for server/tests/skinned_api.rs:
//   node tools/browser/skinned.mjs BASE_URL SCENE OUT_DIR T1 T2
// The viewer looks at the scene's origin from 10 m along +z, 2 m up, at
// the times T1 and T2 (seconds). Prints one JSON object: per time, the
// top-most row of scene pixels within 60 pixels of the canvas's centre
// column, and the drawn clusters; the pixels that differ between the two
// pictures (kept in OUT_DIR); and the page's errors.
import { mkdirSync } from "node:fs";
import { launch } from "./launch.mjs";
import { BACKGROUND, canvasShot, compare, hook, openScene, settle } from "./page.mjs";

const [base, scene, outDir, t1, t2] = process.argv.slice(2);
if (!t2) {
  console.error("usage: node skinned.mjs BASE_URL SCENE OUT_DIR T1 T2");
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const [width, height] = [800, 600];
const out = { errors: [], shots: [] };
const browser = await launch();
try {
  const page = await openScene(browser, base, scene, width, height, out.errors);
  await hook(page, (v) => v.setCamera({ target: [0, 2, 0], distance: 10, azimuth: Math.PI / 2, elevation: 0 }));
  const pictures = [];
  for (const t of [Number(t1), Number(t2)]) {
    await hook(page, (v, t) => v.setTime(t), t);
    const state = await settle(page);
    const png = await canvasShot(page);
    pictures.push(png);
    const top = await page.evaluate(async ([data, bg]) => {
      const img = await createImageBitmap(await (await fetch(`data:image/png;base64,${data}`)).blob());
      const c = new OffscreenCanvas(img.width, img.height);
      const g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      const px = g.getImageData(0, 0, img.width, img.height).data;
      const centre = Math.floor(img.width / 2);
      for (let y = 0; y < img.height; y++) {
        for (let x = centre - 60; x <= centre + 60; x++) {
          const i = 4 * (y * img.width + x);
          if (Math.abs(px[i] - bg[0]) + Math.abs(px[i + 1] - bg[1]) + Math.abs(px[i + 2] - bg[2]) > 12) return y;
        }
      }
      return null;
    }, [png.toString("base64"), BACKGROUND]);
    out.shots.push({ t, top, clusters: state.clusters, ids: state.ids });
  }
  out.diff = await compare(page, outDir, "skinned", pictures[0], pictures[1], { x: 0, y: 0, width, height });
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
