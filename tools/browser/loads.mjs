// A cut that brings well over a thousand new clusters at once, some of
// whose geometry requests fail, for server/tests/viewer_browser.rs:
//   node tools/browser/loads.mjs BASE_URL SCENE TIME
// Opens the viewer at a coarse pixel error, then lowers it so that the
// next cut adds most of the tree's leaves, which the page asks for in
// batches (`.../geometry?h=...`). The first request of every FAIL_EVERY-th
// geometry URL is refused by the browser (as it refuses fetches when too
// many are pending), so the page has to try again on its own. Prints
// one JSON object: the drawn cut before and after, the requests seen, the
// most in flight at once, and the server's cut for the drawn request.
import { launch } from "./launch.mjs";
import { hook } from "./page.mjs";

const [base, scene, time] = process.argv.slice(2);
if (!base || !scene || !time) {
  console.error("usage: node loads.mjs BASE_URL SCENE TIME");
  process.exit(2);
}
const FAIL_EVERY = 3;
const out = { errors: [] };

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 960, height: 600 } });
  page.on("pageerror", (e) => out.errors.push(`page error: ${e.message}`));
  page.on("console", (m) => {
    // The refused requests are reported by the browser itself.
    if (m.type() === "error" && !m.text().includes("net::ERR_FAILED")) out.errors.push(`console: ${m.text()}`);
  });

  const isGlb = (url) => new URL(url).pathname.includes("/geometry");
  let inFlight = 0;
  const requests = { total: 0, refused: 0, distinct: new Set(), peak: 0 };
  page.on("request", (r) => {
    if (!isGlb(r.url())) return;
    inFlight++;
    requests.peak = Math.max(requests.peak, inFlight);
  });
  for (const done of ["requestfinished", "requestfailed"]) {
    page.on(done, (r) => {
      if (isGlb(r.url())) inFlight--;
    });
  }

  const settled = (timeout) =>
    page
      .waitForFunction(() => window.hdlodViewer && window.hdlodViewer.settled(), null, { timeout, polling: 100 })
      .then(() => page.evaluate(() => window.hdlodViewer.state()));

  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}&time=${encodeURIComponent(time)}&pixel_error=8`);
  const coarse = await settled(60000);
  out.before = { clusters: coarse.clusters, glbFiles: coarse.glbFiles };

  await page.route((url) => url.pathname.includes("/geometry"), (route) => {
    const url = route.request().url();
    requests.total++;
    const first = !requests.distinct.has(url);
    requests.distinct.add(url);
    if (first && requests.distinct.size % FAIL_EVERY === 0) {
      requests.refused++;
      return route.abort("failed");
    }
    return route.continue();
  });
  await hook(page, (v, p) => v.setPixelError(p), 0.05);
  const fine = await settled(240000);
  out.after = {
    clusters: fine.clusters,
    ids: fine.ids,
    missing: fine.missing,
    loadsPeak: fine.loadsPeak,
    loadRetries: fine.loadRetries,
    glbFiles: fine.glbFiles,
    error: fine.error,
  };
  out.requests = { total: requests.total, refused: requests.refused, distinct: requests.distinct.size, peak: requests.peak };
  out.serverCut = await page.evaluate(async ([name, body]) => {
    const r = await fetch(`/api/v1/scenes/${encodeURIComponent(name)}/cut`, {
      method: "POST",
      headers: { "content-type": "application/json" },
      body: JSON.stringify(body),
    });
    return (await r.json()).clusters.map((c) => c.id).sort((a, b) => a - b);
  }, [scene, await page.evaluate(() => window.hdlodViewer.lastRequest())]);
} catch (e) {
  out.errors.push(`driver: ${e.stack || e}`);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
