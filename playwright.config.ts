import { defineConfig, devices } from '@playwright/test';
import { CHROMIUM, chromiumArgs } from './scripts/chromium.mjs';

// Playwright drives Debian's Chromium (/usr/bin/chromium, installed by scripts/setup.mjs;
// its switches in scripts/chromium.mjs);
// it never downloads a browser of its own. WebGL2 runs on SwiftShader (software), so the tests
// need no GPU.
// PW_PORT: another port when several checkouts run their tests on one machine (an existing
// server on the port is reused outside CI, whichever checkout it serves).
const PORT = Number(process.env.PW_PORT) || 5199;

export default defineConfig({
  testDir: 'tests/e2e',
  outputDir: 'test-results/playwright',
  fullyParallel: false,
  workers: 1,
  retries: 0,
  timeout: 60_000,
  expect: { timeout: 15_000 },
  forbidOnly: !!process.env.CI,
  reporter: [['list']],
  use: {
    ...devices['Desktop Chrome'],
    baseURL: `http://127.0.0.1:${PORT}`,
    // Half HD: software WebGL draws it 1.5× as fast as 1280×720 (the demo at a fixed step: 46
    // against 30 frames a second), and most tests wait on frames; the pages' layouts fit it.
    viewport: { width: 640, height: 360 },
    screenshot: 'only-on-failure',
    trace: 'off',
    launchOptions: {
      executablePath: CHROMIUM,
      args: chromiumArgs(),
    },
  },
  projects: [{ name: 'chromium' }],
  webServer: {
    command: `node_modules/.bin/vite --host 127.0.0.1 --port ${PORT} --strictPort`,
    url: `http://127.0.0.1:${PORT}/`,
    reuseExistingServer: !process.env.CI,
    timeout: 60_000,
    stdout: 'ignore',
    stderr: 'pipe',
  },
});
