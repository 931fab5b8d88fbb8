// What the viewer's browser drivers share: waiting for a settled view,
// calling the page's test hook (window.hdlodViewer, docs/viewer.md),
// screenshots of the canvas alone and their pixels, decoded by the page's
// own image decoder.
import { writeFileSync } from "node:fs";
import { join } from "node:path";

export const BACKGROUND = [219, 227, 237];

// Overlays hidden for a shot of the 3D view alone.
const OVERLAYS = "#bar, #panel, #stats, #legend, #help";

// The drawn cut answers the view, nothing loads, the panel and the colour
// mode are up to date; then one more frame so the canvas shows it.
export async function settle(p) {
  await p.waitForFunction(() => window.hdlodViewer && window.hdlodViewer.settled() && window.hdlodViewer.panelSettled(), null, {
    timeout: 30000,
    polling: 50,
  });
  await p.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  return p.evaluate(() => window.hdlodViewer.state());
}

// A page of `width` x `height` on the viewer at `base` showing `scene`,
// settled; its script errors and console errors go to `errors`.
export async function openScene(browser, base, scene, width, height, errors) {
  const page = await browser.newPage({ viewport: { width, height } });
  page.on("pageerror", (e) => errors.push(`page error: ${e.message}`));
  page.on("console", (m) => {
    if (m.type() === "error") errors.push(`console: ${m.text()}`);
  });
  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}`);
  await settle(page);
  return page;
}

// f(hook, arg) run in the page against the test hook.
export function hook(p, f, arg) {
  return p.evaluate(([body, a]) => new Function("v", "a", `return (${body})(v, a)`)(window.hdlodViewer, a), [f.toString(), arg]);
}

export async function canvasShot(p) {
  await p.evaluate((sel) => document.querySelectorAll(sel).forEach((e) => (e.style.visibility = "hidden")), OVERLAYS);
  const png = await p.screenshot();
  await p.evaluate((sel) => document.querySelectorAll(sel).forEach((e) => (e.style.visibility = "")), OVERLAYS);
  return png;
}

// The RGB of each CSS pixel [x, y] of a screenshot (device scale 1).
export function pixelsAt(p, png, points) {
  return p.evaluate(async ([data, points]) => {
    const img = await createImageBitmap(await (await fetch(`data:image/png;base64,${data}`)).blob());
    const c = new OffscreenCanvas(img.width, img.height);
    const g = c.getContext("2d");
    g.drawImage(img, 0, 0);
    const px = g.getImageData(0, 0, img.width, img.height).data;
    return points.map(([x, y]) => {
      const i = 4 * (Math.floor(y) * img.width + Math.floor(x));
      return [px[i], px[i + 1], px[i + 2]];
    });
  }, [png.toString("base64"), points]);
}

// Two screenshots compared over the region `clip`: pixels that differ, and
// the pixels off the background in each. Both are kept in outDir.
export function compare(p, outDir, name, a, b, clip) {
  for (const [suffix, png] of [["a", a], ["b", b]]) writeFileSync(join(outDir, `${name}-${suffix}.png`), png);
  return p.evaluate(async ([da, db, clip, bg]) => {
    const load = async (d) => {
      const img = await createImageBitmap(await (await fetch(`data:image/png;base64,${d}`)).blob());
      const c = new OffscreenCanvas(img.width, img.height);
      const g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      return g.getImageData(clip.x, clip.y, clip.width, clip.height).data;
    };
    const [pa, pb] = [await load(da), await load(db)];
    const off = (px, i) => Math.abs(px[i] - bg[0]) + Math.abs(px[i + 1] - bg[1]) + Math.abs(px[i + 2] - bg[2]) > 12;
    let differ = 0;
    let offA = 0;
    let offB = 0;
    for (let i = 0; i < pa.length; i += 4) {
      if (Math.abs(pa[i] - pb[i]) + Math.abs(pa[i + 1] - pb[i + 1]) + Math.abs(pa[i + 2] - pb[i + 2]) > 24) differ++;
      if (off(pa, i)) offA++;
      if (off(pb, i)) offB++;
    }
    return { pixels: pa.length / 4, differ, offA, offB };
  }, [a.toString("base64"), b.toString("base64"), clip, BACKGROUND]);
}
