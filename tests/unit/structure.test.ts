// The library's shape, checked on the source: pages use only the public entry and stay small,
// the raw layer mirrors the bindings and is the only importer of the generated package, the
// runtime has one forward kinematics and one two-bone IK, and nothing points outside the repo.
import fs from 'node:fs';
import path from 'node:path';
import { describe, expect, it } from 'vitest';

const ROOT = path.resolve(import.meta.dirname, '../..');
const WEB = path.join(ROOT, 'web/src');

function files(dir: string, ext: RegExp): string[] {
  return fs.readdirSync(dir, { withFileTypes: true }).flatMap((e) => {
    const p = path.join(dir, e.name);
    if (e.isDirectory()) return e.name === 'pkg' ? [] : files(p, ext);
    return ext.test(e.name) ? [p] : [];
  });
}

/** Module specifiers of a TS file's static and dynamic imports and re-exports. */
function imports(file: string): string[] {
  const text = fs.readFileSync(file, 'utf8');
  return [...text.matchAll(/(?:^|\n)\s*(?:import|export)\b[^'"]*?from\s+['"]([^'"]+)['"]|import\(\s*['"]([^'"]+)['"]\s*\)|(?:^|\n)\s*import\s+['"]([^'"]+)['"]/g)].map((m) => m[1] ?? m[2] ?? m[3]);
}

const lines = (file: string) => fs.readFileSync(file, 'utf8').split('\n').length;
const rel = (file: string) => path.relative(ROOT, file);
const source = (file: string) => !/\.test\.ts$/.test(file);

/** The package's public entries (package.json `exports`: `mm-avatar`, `mm-avatar/vr`, `mm-avatar/rooms`) and their API reference pages. */
const ENTRIES = [
  { file: 'index.ts', name: 'mm-avatar', docs: 'docs/api/mm-avatar/README.md' },
  { file: 'vr/index.ts', name: 'mm-avatar/vr', docs: 'docs/api/mm-avatar/vr/README.md' },
  { file: 'rooms/index.ts', name: 'mm-avatar/rooms', docs: 'docs/api/mm-avatar/rooms/README.md' },
];

describe('pages are built on the public entries only', () => {
  const pages = fs.readdirSync(path.join(WEB, 'pages'), { withFileTypes: true }).filter((e) => e.isDirectory()).map((e) => e.name);

  it('has the five pages', () => {
    expect(pages.sort()).toEqual(['bench', 'crowd', 'demo', 'viewer', 'vr']);
  });

  for (const page of pages) {
    it(`${page}: imports only the public entries ('../../index.ts', '../../vr/index.ts', '../../rooms/index.ts'), the pages' kit ('../kit.ts') and third-party packages; ≤ 250 lines`, () => {
      const ts = files(path.join(WEB, 'pages', page), /\.ts$/).filter(source);
      expect(ts.length).toBeGreaterThan(0);
      for (const f of ts) {
        for (const spec of imports(f)) {
          if (!spec.startsWith('.')) continue; // a package: three, lil-gui, iwer
          expect([...ENTRIES.map((e) => `../../${e.file}`), '../kit.ts'], `${rel(f)} imports ${spec}`).toContain(spec);
        }
      }
      const total = ts.reduce((n, f) => n + lines(f), 0);
      expect(total, `${page}: ${total} lines`).toBeLessThanOrEqual(250);
    });

    it(`${page}: no line over 120 characters`, () => {
      for (const f of files(path.join(WEB, 'pages', page), /\.(ts|css)$/).filter(source)) {
        const long = fs.readFileSync(f, 'utf8').split('\n').flatMap((l, i) => ([...l].length > 120 ? [`${rel(f)}:${i + 1}`] : []));
        expect(long, 'lines over 120 characters').toEqual([]);
      }
    });
  }

  it('the HTML pages load their page module and nothing else of the library', () => {
    for (const html of ['index.html', 'viewer.html', 'vr.html', 'bench.html']) {
      const scripts = [...fs.readFileSync(path.join(ROOT, html), 'utf8').matchAll(/<script[^>]*src="([^"]+)"/g)].map((m) => m[1]);
      expect(scripts.length, html).toBe(1);
      expect(scripts[0], html).toMatch(/^\/web\/src\/pages\/[a-z]+\/main\.ts$/);
    }
  });
});

describe('the raw layer', () => {
  it('core/raw.ts is the only importer of the generated package', () => {
    for (const f of files(WEB, /\.ts$/)) {
      for (const spec of imports(f)) if (/pkg\//.test(spec)) expect(rel(f), spec).toBe('web/src/core/raw.ts');
    }
  });

  it('mirrors wasm-core/src/bindings/ file for file', () => {
    const rust = fs.readdirSync(path.join(ROOT, 'wasm-core/src/bindings')).filter((f) => f !== 'mod.rs').map((f) => f.replace(/\.rs$/, ''));
    const ts = fs.readdirSync(path.join(WEB, 'core')).filter((f) => f.endsWith('.ts') && !f.endsWith('.test.ts')).map((f) => f.replace(/\.ts$/, ''));
    for (const r of rust) expect(ts, `bindings/${r}.rs has no core/${r}.ts`).toContain(r);
  });

  it('core/ imports only itself and the fetch and asset helpers (not devices, views or pages)', () => {
    for (const f of files(path.join(WEB, 'core'), /\.ts$/).filter(source)) {
      for (const spec of imports(f)) {
        if (!spec.startsWith('.')) continue;
        expect(['./', '../fetch.ts', '../assets.ts'].some((ok) => spec.startsWith(ok) || spec === ok), `${rel(f)} imports ${spec}`).toBe(true);
      }
    }
  });
});

describe('one of each', () => {
  const rust = files(path.join(ROOT, 'wasm-core/src'), /\.rs$/);
  const ts = files(WEB, /\.ts$/).filter(source);

  it('one forward kinematics: kinematics.rs in Rust, none in TS', () => {
    const defs = rust.filter((f) => /fn (local_to_model|forward_kinematics)\s*[<(]/.test(fs.readFileSync(f, 'utf8')));
    expect(defs.map(rel)).toContain('wasm-core/src/runtime/kinematics.rs');
    // Other `forward_kinematics` methods (database, pose) only call the one function.
    for (const f of defs) if (rel(f) !== 'wasm-core/src/runtime/kinematics.rs') expect(fs.readFileSync(f, 'utf8'), rel(f)).toMatch(/local_to_model\(/);
    for (const f of ts) expect(fs.readFileSync(f, 'utf8'), rel(f)).not.toMatch(/function\s+forwardKinematics|forwardKinematics\s*\(/);
  });

  it('one two-bone IK: ik.rs in Rust; TS calls it through its binding', () => {
    const defs = rust.filter((f) => /fn two_bone_ik\w*\s*\(/.test(fs.readFileSync(f, 'utf8')));
    expect(defs.map(rel)).toEqual(['wasm-core/src/runtime/ik.rs']);
    for (const f of ts) expect(fs.readFileSync(f, 'utf8'), rel(f)).not.toMatch(/solveTwoBone|lawOfCosines/);
  });

  it('one role vocabulary: roles.rs; TS reads it through the binding', () => {
    const defs = rust.filter((f) => /fn find_roles\s*[<(]/.test(fs.readFileSync(f, 'utf8')));
    expect(defs.map(rel)).toEqual(['wasm-core/src/runtime/roles.rs']);
    for (const f of ts) expect(fs.readFileSync(f, 'utf8'), rel(f)).not.toMatch(/JOINT_NAME_TABLE|\/foot\|ankle\|toe\/i/);
  });
});

describe('runtime and offline apart (wasm-core/src/runtime, offline, harness)', () => {
  const SRC = path.join(ROOT, 'wasm-core/src');
  const OFFLINE = fs.readdirSync(path.join(SRC, 'offline')).map((f) => f.replace(/\.rs$/, '')).filter((m) => m !== 'mod');
  const HARNESS = fs.readdirSync(path.join(SRC, 'harness')).map((f) => f.replace(/\.rs$/, '')).filter((m) => m !== 'mod');
  /** A file's code without its comments (doc links may name any module). */
  const code = (f: string) => fs.readFileSync(f, 'utf8').split('\n').filter((l) => !/^\s*\/\//.test(l)).join('\n');

  it('no runtime module imports an offline module or a harness', () => {
    expect(OFFLINE).toEqual(expect.arrayContaining(['builder', 'bvh', 'config', 'gltf']));
    expect(HARNESS).toEqual(expect.arrayContaining(['quality', 'vr_replay']));
    const banned = new RegExp(`\\b(crate|super)::(offline|harness|${[...OFFLINE, ...HARNESS].join('|')})\\b|use crate::\\{[^}]*\\b(${[...OFFLINE, ...HARNESS].join('|')})\\b`);
    const runtime = files(path.join(SRC, 'runtime'), /\.rs$/);
    expect(runtime.length).toBeGreaterThan(15);
    for (const f of runtime) expect(code(f), rel(f)).not.toMatch(banned);
  });

  it('no Rust source reads a file from web/ (shared settings live in settings/)', () => {
    for (const f of files(SRC, /\.rs$/)) expect(code(f), rel(f)).not.toMatch(/include_(str|bytes)!\([^)]*web\//);
    expect(fs.existsSync(path.join(ROOT, 'settings/vr-settings.json'))).toBe(true);
  });
});

describe('what the builds keep', () => {
  it("no source imports one of the library's modules for its side effects alone", () => {
    // package.json's `sideEffects` names only the built entries, so a bundler (ours, and an
    // app's) drops a module imported for its side effects alone: element/early.ts' cache reads
    // were in no build for three stops (docs/history.md "Loading", stop 60). Stylesheets are kept.
    const ts = files(WEB, /\.ts$/).filter(source);
    expect(ts.length).toBeGreaterThan(100);
    const bare = /(?:^|\n)\s*import\s+['"](\.{1,2}\/[^'"]+)['"]/g;
    const found = ts.flatMap((f) => [...fs.readFileSync(f, 'utf8').matchAll(bare)].map((m) => m[1]).filter((s) => !s.endsWith('.css')).map((s) => `${rel(f)}: ${s}`));
    expect(found).toEqual([]);
  });
});

describe('the repository stands alone', () => {
  it('no source, test or doc points outside the repository', () => {
    const all = [
      ...files(path.join(ROOT, 'wasm-core/src'), /\.rs$/),
      ...files(path.join(ROOT, 'wasm-core/tests'), /\.rs$/),
      ...files(WEB, /\.(ts|css)$/),
      ...files(path.join(ROOT, 'tests'), /\.ts$/).filter((f) => !f.endsWith('structure.test.ts')),
      ...files(path.join(ROOT, 'docs'), /\.md$/),
      path.join(ROOT, 'README.md'),
    ];
    const outside = new RegExp(['THESIS', 'NOTES'].join('_') + '|shared/docs|DESIGN\\.md');
    for (const f of all) expect(fs.readFileSync(f, 'utf8'), rel(f)).not.toMatch(outside);
  });
});

describe('the API reference', () => {
  for (const entry of ENTRIES) {
    it(`docs/api (npm run docs) lists every name ${entry.name} (web/src/${entry.file}) exports`, () => {
      const text = fs.readFileSync(path.join(WEB, entry.file), 'utf8');
      const names = [...text.matchAll(/export (?:type )?\{([^}]+)\}/g)].flatMap((m) => m[1].split(',').map((n) => n.trim().replace(/^type /, '')).filter(Boolean));
      const index = fs.readFileSync(path.join(ROOT, entry.docs), 'utf8');
      expect(names.length).toBeGreaterThan(20);
      const missing = names.filter((n) => !index.includes(`[${n.replace(/_/g, '\\_')}]`));
      expect(missing, 'run `npm run docs`').toEqual([]);
    });
  }

  it('the three entries share no name, and VR and rooms are not in the root entry', () => {
    const exported = (file: string) => new Set([...fs.readFileSync(path.join(WEB, file), 'utf8').matchAll(/export (?:type )?\{([^}]+)\}/g)].flatMap((m) => m[1].split(',').map((n) => n.trim().replace(/^type /, '')).filter(Boolean)));
    const [root, vr, rooms] = ENTRIES.map((e) => exported(e.file));
    for (const n of [...vr, ...rooms]) expect(root.has(n), `${n} is exported by the root entry too`).toBe(false);
    for (const n of vr) expect(rooms.has(n), `${n} is exported by both vr and rooms`).toBe(false);
  });

  it('the public API is the list in tests/unit/public-api.json, ≤ 80 names in the root entry (a change updates it on purpose)', () => {
    const exported = (file: string) => [...fs.readFileSync(path.join(WEB, file), 'utf8').matchAll(/export (?:type )?\{([^}]+)\}/g)].flatMap((m) => m[1].split(',').map((n) => n.trim().replace(/^type /, '')).filter(Boolean)).sort();
    const actual = Object.fromEntries(ENTRIES.map((e) => [e.name, exported(e.file)]));
    const listed = JSON.parse(fs.readFileSync(path.join(ROOT, 'tests/unit/public-api.json'), 'utf8')) as Record<string, string[]>;
    expect(actual, 'the entries export other names than tests/unit/public-api.json lists: update it (and docs/api) on purpose').toEqual(listed);
    expect(actual['mm-avatar'].length).toBeLessThanOrEqual(80);
  });

  it('package.json exports each entry with its types', () => {
    const pkg = JSON.parse(fs.readFileSync(path.join(ROOT, 'package.json'), 'utf8')) as { exports: Record<string, { types: string; import: string } | string> };
    for (const entry of ENTRIES) {
      const key = entry.name === 'mm-avatar' ? '.' : `./${entry.name.slice('mm-avatar/'.length)}`;
      const target = pkg.exports[key];
      expect(typeof target === 'object' && target.types, key).toBe(`./dist/types/${entry.file.replace(/\.ts$/, '.d.ts')}`);
    }
  });
});
