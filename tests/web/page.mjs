// Opens the web page in headless Chromium (Debian's, driven by playwright-core from npm) as a
// visitor would, in real time: waits until the page says it is done streaming (or has failed),
// then prints its state as one JSON line (the body's data attributes) and, with SHOT, saves a
// screenshot of the 800 x 600 window. Real time matters: the page measures its own step latency,
// which Chromium's virtual time (what --dump-dom runs under) would freeze.
//
//   TROUPE_NPM_MODULES=DIR node tests/web/page.mjs URL [SHOT]
//
// TROUPE_HOLD=KEY holds a key down from when the page is ready (the steered actor's arrows);
// TROUPE_TOKENS=N waits for N tokens instead of the end of a fixed stream (live streaming);
// TROUPE_DROP=FILE drops that file on the page once it is ready, as a visitor dragging it from
// their desktop would (a drop event carrying the file), and waits for it to stream.
import { createRequire } from "node:module";
import { readFileSync } from "node:fs";
import { basename, join, resolve } from "node:path";

const require = createRequire(join(resolve(process.env.TROUPE_NPM_MODULES), "noop.js"));
const { chromium } = require("playwright-core");

const [url, shot] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.TROUPE_CHROMIUM || "/usr/bin/chromium",
  args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars"],
});
try {
  const page = await browser.newPage({ viewport: { width: 800, height: 600 }, deviceScaleFactor: 1 });
  const console_ = [];
  page.on("console", (m) => console_.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => console_.push(`pageerror: ${e.message}`));
  await page.goto(url);
  const ready = () => page.waitForFunction(
    () => document.body.dataset.ready === "1" || document.body.dataset.error, null, { timeout: 120000 });
  if (process.env.TROUPE_HOLD) {
    await ready();
    await page.keyboard.down(process.env.TROUPE_HOLD);
  }
  if (process.env.TROUPE_DROP) {
    await ready();
    const name = basename(process.env.TROUPE_DROP);
    const bytes = [...readFileSync(process.env.TROUPE_DROP)];
    await page.evaluate(({ name, bytes }) => {
      const files = new DataTransfer();
      files.items.add(new File([new Uint8Array(bytes)], name));
      for (const type of ["dragover", "drop"]) {
        window.dispatchEvent(new DragEvent(type, { dataTransfer: files, bubbles: true, cancelable: true }));
      }
    }, { name, bytes });
    await page.waitForFunction((name) => document.body.dataset.actor === name || document.body.dataset.error ||
      document.body.dataset.refused, name, { timeout: 120000 });
  }
  const tokens = Number(process.env.TROUPE_TOKENS || 0);
  await page.waitForFunction(
    (n) => (n > 0 ? Number(document.body.dataset.tokens) >= n : document.body.dataset.done === "1") ||
      document.body.dataset.error,
    tokens, { timeout: 120000 });
  // One more picture after the last step, so the screenshot shows the final state.
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  const state = await page.evaluate(() => ({ ...document.body.dataset }));
  if (process.env.TROUPE_HOLD) await page.keyboard.up(process.env.TROUPE_HOLD);
  if (shot) await page.screenshot({ path: shot });
  console.log(JSON.stringify({ state, console: console_ }));
} finally {
  await browser.close();
}
