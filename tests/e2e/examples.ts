// The example apps of examples/ as a user gets them: `npm pack` of this checkout, each example
// copied to its own folder with its `mm-avatar` dependency pointing at the tarball, installed
// from the registry, built with its own `npm run build`. Cached in
// node_modules/.cache/mm-examples/: the install is redone when the example's package.json
// changes (a new tarball only reinstalls the package), the build when the tarball or the
// example's files change; an unchanged checkout reuses both. Asynchronous, so the apps install
// and build side by side (the installs mostly wait on the registry).
import { execFile, execFileSync } from 'node:child_process';
import { createHash } from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import { promisify } from 'node:util';

const ROOT = path.resolve(import.meta.dirname, '../..');
const CACHE = path.join(ROOT, 'node_modules', '.cache', 'mm-examples');

export interface Packed {
  tarball: string;
  /** sha256 of the tarball, 16 hex digits. */
  hash: string;
}

export interface Example {
  name: string;
  /** The installed and built copy. */
  dir: string;
  /** Its build output (served statically). */
  dist: string;
}

const sha = (data: string | Buffer) => createHash('sha256').update(data).digest('hex').slice(0, 16);
const log = (m: string) => console.log(`[examples] ${m}`);

async function run(cmd: string, args: string[], cwd: string): Promise<void> {
  const t0 = performance.now();
  try {
    await promisify(execFile)(cmd, args, { cwd, encoding: 'utf8', maxBuffer: 64 << 20, env: { ...process.env, npm_config_update_notifier: 'false' } });
  } catch (e) {
    const err = e as { stdout?: string; stderr?: string; message: string };
    throw new Error(`\`${cmd} ${args.join(' ')}\` failed in ${path.relative(ROOT, cwd)}:\n${err.stdout ?? ''}${err.stderr ?? err.message}`);
  }
  log(`${cmd} ${args.join(' ')} (${path.relative(ROOT, cwd)}): ${((performance.now() - t0) / 1000).toFixed(1)} s`);
}

let packedOnce: Packed | null = null;

/** `npm pack` of this checkout (dist/ must be built) into the cache; once per test run. */
export function packTarball(): Packed {
  if (packedOnce) return packedOnce;
  fs.mkdirSync(CACHE, { recursive: true });
  const out = execFileSync('npm', ['pack', '--json', '--pack-destination', CACHE], { cwd: ROOT, encoding: 'utf8', env: { ...process.env, npm_config_update_notifier: 'false' } });
  const [info] = JSON.parse(out) as { filename: string; size: number; unpackedSize: number; entryCount: number }[];
  const tarball = path.join(CACHE, info.filename);
  packedOnce = { tarball, hash: sha(fs.readFileSync(tarball)) };
  log(`packed ${info.filename}: ${(info.size / 1e6).toFixed(1)} MB, ${(info.unpackedSize / 1e6).toFixed(1)} MB unpacked, ${info.entryCount} files (sha256 ${packedOnce.hash})`);
  return packedOnce;
}

/** The example's own files (no node_modules, no build output), relative paths, sorted. */
function sourceFiles(dir: string, prefix = ''): string[] {
  return fs
    .readdirSync(dir, { withFileTypes: true })
    .filter((e) => !['node_modules', 'dist', 'package-lock.json'].includes(e.name))
    .flatMap((e) => (e.isDirectory() ? sourceFiles(path.join(dir, e.name), `${prefix}${e.name}/`) : [`${prefix}${e.name}`]))
    .sort();
}

/** Installs (from the tarball and the registry) and builds examples/<name>, reusing the cache. */
export async function prepareExample(name: string, packed: Packed): Promise<Example> {
  const src = path.join(ROOT, 'examples', name);
  const dir = path.join(CACHE, name);
  const dist = path.join(dir, 'dist');
  const pkg = JSON.parse(fs.readFileSync(path.join(src, 'package.json'), 'utf8')) as { dependencies: Record<string, string> };
  if (!pkg.dependencies['mm-avatar']) throw new Error(`examples/${name}/package.json does not depend on mm-avatar`);
  // What a user would have after `npm i <tarball>`.
  pkg.dependencies['mm-avatar'] = `file:${packed.tarball}`;
  const pkgText = `${JSON.stringify(pkg, null, 2)}\n`;
  const files = sourceFiles(src);
  const installKey = sha(pkgText.replace(packed.tarball, ''));
  const buildKey = sha(packed.hash + files.map((f) => f + sha(fs.readFileSync(path.join(src, f)))).join());
  const stamp = (n: string) => path.join(dir, `.mm-${n}`);
  const read = (n: string) => (fs.existsSync(stamp(n)) ? fs.readFileSync(stamp(n), 'utf8') : '');

  if (read('install') !== installKey) {
    fs.rmSync(dir, { recursive: true, force: true });
    fs.mkdirSync(dir, { recursive: true });
  }
  // The example's files, fresh (a removed file goes too).
  for (const f of sourceFiles(dir).filter((f) => !f.startsWith('.mm-') && !f.startsWith('types-'))) fs.rmSync(path.join(dir, f));
  for (const f of files) {
    fs.mkdirSync(path.dirname(path.join(dir, f)), { recursive: true });
    fs.copyFileSync(path.join(src, f), path.join(dir, f));
  }
  fs.writeFileSync(path.join(dir, 'package.json'), pkgText);
  const npm = ['--no-audit', '--no-fund', '--prefer-offline', '--loglevel=error'];
  if (read('install') !== installKey) {
    await run('npm', ['install', ...npm], dir);
    fs.writeFileSync(stamp('install'), installKey);
    fs.writeFileSync(stamp('package'), packed.hash);
  } else if (read('package') !== packed.hash) {
    // Same dependencies, a new tarball: only the package is reinstalled.
    await run('npm', ['install', ...npm, packed.tarball], dir);
    fs.writeFileSync(stamp('package'), packed.hash);
  }
  if (read('build') !== buildKey || !fs.existsSync(dist)) {
    fs.rmSync(dist, { recursive: true, force: true });
    await run('npm', ['run', 'build', '--silent'], dir);
    fs.writeFileSync(stamp('build'), buildKey);
  } else log(`${name}: build up to date (tarball ${packed.hash})`);
  return { name, dir, dist };
}
