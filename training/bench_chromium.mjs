#!/usr/bin/env node
// Median time per OrientationModel.update in headless Chromium (Debian's /usr/bin/chromium via
// playwright-core): serves the repo with vite (cross-origin isolated, for the 5 µs timer), opens
// web/src/orientation/bench.html and prints its result as JSON. Also checks the browser's
// outputs against the recorded PyTorch ones. Usage: node training/bench_chromium.mjs
import { launchBenchChromium, startBenchServer } from '../scripts/bench-server.mjs';

const server = await startBenchServer(5287);
let code = 0;
const browser = await launchBenchChromium({ webgl: false });
try {
  const page = await browser.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(`${server.resolvedUrls.local[0]}web/src/orientation/bench.html`);
  await page.waitForFunction(() => window.__orientationBench?.done, null, { timeout: 300_000, polling: 200 });
  const r = await page.evaluate(() => window.__orientationBench);
  if (r.error || errors.length) throw new Error(r.error ?? errors.join('\n'));
  console.log(JSON.stringify(r, null, 1));
  const g = r.recurrent;
  console.log(`chromium: median ${r.medianMs.toFixed(3)} ms per update (p95 ${r.p95Ms.toFixed(3)} ms), ` +
    `max |output − PyTorch| ${r.maxOutputError.toExponential(2)}; recurrent model: median ${g.medianMs.toFixed(3)} ms ` +
    `(p95 ${g.p95Ms.toFixed(3)} ms), max |output − PyTorch| ${g.maxOutputError.toExponential(2)}`);
  if (!(r.maxOutputError < 1e-4 && g.maxOutputError < 1e-4)) {
    console.error('chromium outputs differ from PyTorch by more than 1e-4');
    code = 1;
  }
} catch (e) {
  console.error(`bench_chromium: ${e instanceof Error ? e.message : e}`);
  code = 1;
} finally {
  await browser.close();
  await server.close();
}
process.exit(code);
