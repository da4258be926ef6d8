// How every test and benchmark here launches Chromium: Debian's package (never a downloaded
// browser), headless, with these switches — playwright.config.ts, the browser benchmarks and
// training/bench_chromium.mjs all take them from here.

/** Debian's Chromium (`apt-get install chromium`, scripts/setup.mjs). */
export const CHROMIUM = '/usr/bin/chromium';

// Chromium 156's headless shell builds the omnibox's WebUI popup (lit, the composebox) in a
// renderer of its own for every new tab: ~0.5 s of CPU, on one of this machine's two cores,
// while the page under test loads (measured: an embed visit's first frame 654–685 → 468–474 ms
// warm with it off). No page can see or cause it; a browser with a window has it ready long
// before. Chromium keeps only the last `--disable-features` switch, and playwright-core passes
// its own list first, so this one repeats playwright-core 1.65's (PaintHolding and the rest
// stay off) and adds the popup's three features.
const DISABLED_FEATURES = [
  'AvoidUnnecessaryBeforeUnloadCheckSync',
  'DestroyProfileOnBrowserClose',
  'HttpsUpgrades',
  'HttpsFirstBalancedModeAutoEnable',
  'LensOverlay',
  'MediaRouter',
  'PaintHolding',
  'ThirdPartyStoragePartitioning',
  'AvoidCorsURLLoaderRestartOnRedirect',
  'OptimizationHints',
  'NetworkTimeServiceQuerying',
  'AimEnabled',
  'PreconnectToSearch',
  'WebUIOmniboxPopup',
  'WebUIOmniboxFullPopup',
  'WebUIOmniboxAimPopup',
];

/**
 * The switches. `webgl`: software WebGL2 (SwiftShader through ANGLE) for pages that draw; this
 * machine has no GPU.
 */
export function chromiumArgs({ webgl = true } = {}) {
  const args = [
    '--headless',
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
    `--disable-features=${DISABLED_FEATURES.join(',')}`,
  ];
  return webgl ? [...args, '--use-angle=swiftshader', '--enable-unsafe-swiftshader'] : args;
}
