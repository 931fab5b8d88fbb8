// Drives the web viewer across a server restart for
// server/tests/viewer_browser.rs:
//   node tools/browser/reconnect.mjs BASE_URL SCENE CONTROL_FILE
// Opens the viewer and waits for a settled view, prints one JSON line
// (`phase: "ready"`), then waits for CONTROL_FILE, which the test writes
// once it has killed the server and started it again on the same address.
// The view is never moved: the page must reconnect and ask its view again
// by itself. Prints a second JSON line (`phase: "done"`) with the page's
// state before and after.
import { existsSync } from "node:fs";
import { launch } from "./launch.mjs";
import { settle } from "./page.mjs";

const [base, scene, control] = process.argv.slice(2);
if (!base || !scene || !control) {
  console.error("usage: node reconnect.mjs BASE_URL SCENE CONTROL_FILE");
  process.exit(2);
}
const browser = await launch();
const errors = [];
try {
  const p = await browser.newPage({ viewport: { width: 800, height: 500 } });
  p.on("pageerror", (e) => errors.push(e.message));
  await p.goto(`${base}/?scene=${encodeURIComponent(scene)}`);
  const before = await settle(p);
  console.log(JSON.stringify({ phase: "ready", before }));
  const until = Date.now() + 60000;
  while (!existsSync(control)) {
    if (Date.now() > until) throw new Error(`no ${control} within 60 s`);
    await new Promise((r) => setTimeout(r, 50));
  }
  // A new answer (after the one drawn before) that settles the same view.
  await p.waitForFunction((n) => window.hdlodViewer.state().answers > n && window.hdlodViewer.settled(), before.answers, {
    timeout: 30000,
    polling: 50,
  });
  const after = await p.evaluate(() => window.hdlodViewer.state());
  const request = await p.evaluate(() => window.hdlodViewer.lastRequest());
  console.log(JSON.stringify({ phase: "done", before, after, request, errors }));
} finally {
  await browser.close();
}
