// The package in other people's apps (issue 25): `npm pack` of this checkout, then each example
// app of examples/ (vite: a Character from code; webpack: the element; React Three Fiber) is
// installed from the tarball and the registry, built by its own bundler, served by a plain static
// server and opened in Chromium, where the character loads and walks more than 1 m toward a
// `walkTo` target with no failed request and no console error. No file is copied by hand: the
// WASM core, database and avatar reach each app's output through its bundler. Also: the vite
// app's output has no onnxruntime (nor VR model) file; importing every entry in plain Node (SSR)
// touches no DOM global; a consumer TypeScript project type-checks against the packed types with
// moduleResolution bundler and node16.
//
// Installs and builds are cached in node_modules/.cache/mm-examples/ (tests/e2e/examples.ts): an
// unchanged tarball and example reuse the last build; a new tarball reinstalls only the package.
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { expect, test, type Page } from '@playwright/test';
import { type Example, type Packed, packTarball, prepareExample } from './examples.ts';
import { type StaticServer, serveStatic } from './static-server.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const SHOTS = path.join(ROOT, 'test-results');

test.describe.configure({ mode: 'serial' });

let packed: Packed;
/** The three apps, installed and built side by side from the start; each test awaits its own. */
const examples = new Map<string, Promise<Example>>();
const example = (name: string) => examples.get(name) ?? Promise.reject(new Error(`${name} was not prepared`));
test.beforeAll(async () => {
  test.setTimeout(300_000);
  expect(fs.existsSync(path.join(ROOT, 'dist', 'lib', 'index.js')), 'dist/ is built by `npm run build` (npm test builds it)').toBe(true);
  packed = packTarball();
  fs.mkdirSync(SHOTS, { recursive: true });
  for (const name of ['vite-app', 'webpack-app', 'r3f-app']) {
    const ready = prepareExample(name, packed);
    ready.catch(() => undefined); // reported by the test that awaits it
    examples.set(name, ready);
  }
});

type Root = { x: number; z: number };

/**
 * Opens the built app, waits for its character, asks it to walk 3 m and checks it went more than
 * 1 m toward the target; every request answered, no console error.
 */
async function walksInChromium(page: Page, example: Example, root: string, walkTo: string, shot: string): Promise<void> {
  const errors: string[] = [];
  const failed: string[] = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
  page.on('pageerror', (e) => errors.push(e.message));
  page.on('requestfailed', (r) => failed.push(`${r.url()} ${r.failure()?.errorText}`));
  page.on('response', (r) => r.status() >= 400 && failed.push(`${r.url()} HTTP ${r.status()}`));
  const server: StaticServer = await serveStatic(example.dist);
  try {
    await page.goto(`${server.url}/`);
    await page.waitForFunction(`!!(${root})`, null, { timeout: 120_000, polling: 250 });
    const a = (await page.evaluate(`({ x: (${root}).x, z: (${root}).z })`)) as Root;
    const target = { x: a.x + 0.5, z: a.z + 3 };
    await page.evaluate(`${walkTo}(${target.x}, ${target.z})`);
    const toward = (r: Root) => ((r.x - a.x) * (target.x - a.x) + (r.z - a.z) * (target.z - a.z)) / Math.hypot(target.x - a.x, target.z - a.z);
    await page.waitForFunction(
      ([root, a, t]) => {
        const r = (0, eval)(root) as Root;
        return ((r.x - a.x) * (t.x - a.x) + (r.z - a.z) * (t.z - a.z)) / Math.hypot(t.x - a.x, t.z - a.z) > 1.05;
      },
      [root, a, target] as const,
      { timeout: 120_000, polling: 200 },
    );
    const b = (await page.evaluate(`({ x: (${root}).x, z: (${root}).z })`)) as Root;
    console.log(`${example.name}: walked ${toward(b).toFixed(2)} m toward the walkTo target`);
    expect(toward(b)).toBeGreaterThan(1);
    await page.screenshot({ path: path.join(SHOTS, `package-${shot}.png`) });
  } finally {
    await server.close();
  }
  expect(failed, 'failed requests').toEqual([]);
  expect(errors, 'console errors').toEqual([]);
}

test('vite app (Character from code): builds from the tarball, walks; no onnxruntime or VR file in its output', async ({ page }) => {
  test.setTimeout(420_000);
  const app = await example('vite-app');
  const files = listFiles(app.dist);
  console.log(`vite-app output: ${files.join(', ')}`);
  // The shipped assets were found and emitted by vite itself (hashed names).
  expect(files.some((f) => /\.wasm$/.test(f))).toBe(true);
  expect(files.some((f) => /locomotion.*\.mmdb$/.test(f))).toBe(true);
  expect(files.some((f) => /ubc_male.*\.glb$/.test(f))).toBe(true);
  // A desktop app pays for no VR: no onnxruntime JS or WASM, no orientation model, no VR database.
  expect(files.filter((f) => /onnx|ort[-.]|orientation|vr\.mmdb/i.test(f))).toEqual([]);
  const js = files.filter((f) => f.endsWith('.js')).map((f) => fs.readFileSync(path.join(app.dist, f), 'utf8')).join('\n');
  expect(js).not.toMatch(/onnxruntime|InferenceSession/);
  await walksInChromium(page, app, 'window.character?.root', 'window.character.walkTo', 'vite');
});

test('webpack app (the element): builds from the tarball, <mm-avatar> loads and walks', async ({ page }) => {
  test.setTimeout(420_000);
  const app = await example('webpack-app');
  const files = listFiles(app.dist);
  console.log(`webpack-app output: ${files.join(', ')}`);
  expect(files.some((f) => /\.wasm$/.test(f)) && files.some((f) => /\.mmdb$/.test(f)) && files.some((f) => /\.glb$/.test(f))).toBe(true);
  expect(files.filter((f) => /onnx|ort[-.]/i.test(f))).toEqual([]);
  await walksInChromium(page, app, "document.querySelector('mm-avatar')?.character && document.querySelector('mm-avatar').root", "document.querySelector('mm-avatar').walkTo", 'webpack');
});

test('React Three Fiber app: builds from the tarball, the <primitive> character walks', async ({ page }) => {
  test.setTimeout(420_000);
  const app = await example('r3f-app');
  await walksInChromium(page, app, 'window.character?.root', 'window.character.walkTo', 'r3f');
});

test('SSR: importing every entry in plain Node touches no window, document or customElements', async () => {
  const app = await example('vite-app');
  // three.js itself looks for `window` (its devtools hook): it is imported before the traps.
  const script = `
    await import('three'); await import('three/addons/loaders/GLTFLoader.js');
    const touched = [];
    for (const name of ['window', 'document', 'customElements', 'location', 'navigator']) {
      Object.defineProperty(globalThis, name, { configurable: true, get() { touched.push(name); return undefined; } });
    }
    const entries = {};
    for (const id of ['mm-avatar', 'mm-avatar/vr', 'mm-avatar/rooms']) entries[id] = Object.keys(await import(id)).length;
    const beforeElement = [...touched];
    // The element entry registers <mm-avatar> in a browser: it may ask whether there is one.
    delete globalThis.customElements;
    const element = await import('mm-avatar/element');
    console.log(JSON.stringify({ entries, beforeElement, afterElement: touched, defined: element.defineMMAvatar() }));
  `;
  const out = JSON.parse(execFileSync(process.execPath, ['--input-type=module', '-e', script], { cwd: app.dir, encoding: 'utf8' }).trim().split('\n').pop()!) as {
    entries: Record<string, number>;
    beforeElement: string[];
    afterElement: string[];
    defined: boolean;
  };
  console.log(`SSR import: ${JSON.stringify(out)}`);
  expect(out.entries['mm-avatar']).toBeGreaterThan(40);
  expect(out.entries['mm-avatar/vr']).toBeGreaterThan(20);
  expect(out.entries['mm-avatar/rooms']).toBeGreaterThan(20);
  expect(out.beforeElement).toEqual([]);
  expect(out.afterElement.filter((n) => n !== 'customElements')).toEqual([]);
  expect(out.defined).toBe(false); // nothing registered outside a browser
});

/** A consumer's code: every entry's main names, used with their types (errors where they must be). */
const CONSUMER = `
import * as THREE from 'three';
import { Character, DatabaseBuilder, setAssetBase, type CreateOptions } from 'mm-avatar';
import { MMAvatarElement, defineMMAvatar } from 'mm-avatar/element';
import { TrackedDrive, loadNetworkPredictor, orientationModelUrl } from 'mm-avatar/vr';
import { RoomSession, type RoomMemberView } from 'mm-avatar/rooms';

export async function main(scene: THREE.Scene): Promise<number> {
  const options: CreateOptions = { avatar: null };
  const character: Character = await Character.create(options);
  scene.add(character.object3d);
  character.walkTo(3, 2);
  // @ts-expect-error: a database is a Database, URL or bytes, not a number
  await Character.create({ database: 42 });
  // @ts-expect-error: walkTo takes numbers
  character.walkTo('3', 2);
  const el: MMAvatarElement | null = document.querySelector('mm-avatar');
  const members: RoomMemberView[] = [];
  const url: URL = orientationModelUrl(true);
  setAssetBase('https://cdn.example/mm-avatar/');
  return [defineMMAvatar, TrackedDrive, loadNetworkPredictor, RoomSession, DatabaseBuilder, el?.root.x, members, url].length + character.root.x;
}
`;

for (const resolution of ['bundler', 'node16'] as const) {
  test(`types: a consumer project type-checks against the packed package (moduleResolution ${resolution})`, async () => {
    const app = await example('vite-app');
    const dir = path.join(app.dir, `types-${resolution}`);
    fs.rmSync(dir, { recursive: true, force: true });
    fs.mkdirSync(dir);
    fs.writeFileSync(path.join(dir, 'consumer.ts'), CONSUMER);
    const module = resolution === 'bundler' ? 'ESNext' : 'node16';
    // No skipLibCheck: the package's declarations are checked too.
    const config = { compilerOptions: { target: 'ES2022', module, moduleResolution: resolution, lib: ['ES2022', 'DOM', 'DOM.Iterable'], strict: true, noEmit: true, types: [], skipLibCheck: false }, files: ['consumer.ts'] };
    fs.writeFileSync(path.join(dir, 'tsconfig.json'), JSON.stringify(config, null, 2));
    const tsc = path.join(app.dir, 'node_modules', 'typescript', 'bin', 'tsc');
    let output = '';
    try {
      output = execFileSync(process.execPath, [tsc, '-p', dir], { cwd: dir, encoding: 'utf8' });
    } catch (e) {
      output = String((e as { stdout?: string }).stdout ?? e);
    }
    expect(output.trim(), `tsc (${resolution})`).toBe('');
  });
}

function listFiles(dir: string, prefix = ''): string[] {
  return fs.readdirSync(dir, { withFileTypes: true }).flatMap((e) => (e.isDirectory() ? listFiles(path.join(dir, e.name), `${prefix}${e.name}/`) : [`${prefix}${e.name}`]));
}
