// The vite server every browser benchmark runs its page on: 127.0.0.1, the first free port from
// `port` up, no HMR, and cross-origin isolated so that performance.now() has its 5 µs
// resolution instead of 100 µs.
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { CHROMIUM, chromiumArgs } from './chromium.mjs';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');

/**
 * Headless Chromium as the browser benchmarks run it (scripts/chromium.mjs: the Debian package,
 * the switches playwright.config.ts uses); `webgl`: software WebGL (SwiftShader) for pages that draw.
 */
export async function launchBenchChromium({ webgl = false } = {}) {
  const { chromium } = await import('playwright-core');
  return chromium.launch({ executablePath: CHROMIUM, args: chromiumArgs({ webgl }) });
}

/** Starts it; `close()` the result when done. */
export async function startBenchServer(port) {
  const { createServer } = await import('vite');
  const server = await createServer({
    root: ROOT,
    configFile: path.join(ROOT, 'vite.config.ts'),
    logLevel: 'error',
    clearScreen: false,
    server: {
      host: '127.0.0.1',
      port,
      strictPort: false,
      hmr: false,
      headers: { 'Cross-Origin-Opener-Policy': 'same-origin', 'Cross-Origin-Embedder-Policy': 'require-corp' },
    },
  });
  await server.listen();
  return server;
}
