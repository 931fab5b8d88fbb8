// One object's pixels at two times, for server/tests/skinned_api.rs:
//   node tools/browser/walker.mjs BASE_URL SCENE OUT_DIR FEATURE T1 T2 TX,TY,TZ DISTANCE AZIMUTH ELEVATION
// The viewer looks at TX,TY,TZ from DISTANCE metres at AZIMUTH and
// ELEVATION (radians, as its test hook takes them) at the times T1 and T2
// (seconds). Prints one JSON object: per time, the pixels the feature
// FEATURE covers (every third pixel, from the viewer's pick pass, which
// skins as the drawing does) and the drawn clusters; the pixels of the
// pictures that differ (kept in OUT_DIR); and the page's errors.
import { mkdirSync } from "node:fs";
import { launch } from "./launch.mjs";
import { canvasShot, compare, hook, openScene, settle } from "./page.mjs";

const [base, scene, outDir, feature, t1, t2, target, distance, azimuth, elevation] = process.argv.slice(2);
if (!elevation) {
  console.error("usage: node walker.mjs BASE_URL SCENE OUT_DIR FEATURE T1 T2 TX,TY,TZ DISTANCE AZIMUTH ELEVATION");
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const [width, height] = [800, 600];
const out = { errors: [], shots: [] };
const browser = await launch();
try {
  const page = await openScene(browser, base, scene, width, height, out.errors);
  const camera = { target: target.split(",").map(Number), distance: Number(distance), azimuth: Number(azimuth), elevation: Number(elevation) };
  await hook(page, (v, c) => v.setCamera(c), camera);
  const pictures = [];
  for (const t of [Number(t1), Number(t2)]) {
    await hook(page, (v, t) => v.setTime(t), t);
    const state = await settle(page);
    pictures.push(await canvasShot(page));
    const pixels = await hook(page, (v, id) => v.featurePixels([id], 1e6)[id], Number(feature));
    out.shots.push({ t, pixels, clusters: state.clusters, ids: state.ids });
  }
  out.diff = await compare(page, outDir, "walker", pictures[0], pictures[1], { x: 0, y: 0, width, height });
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
