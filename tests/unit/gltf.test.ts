// Motion in the web's formats (issue 25): a GLB with animation clips and a VRM Animation
// (.vrma), made here from a ../shared BVH take with @gltf-transform (tests/unit/gltf-fixtures.ts),
// each build a database with the WASM builder (as a page does) and with the native `mmdb build`;
// the databases match the BVH's own (the same world motion, whatever the bones' axes, units and
// parent nodes), a character walks on them, and broken files give errors naming the file and
// what is wrong.
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { CharacterRuntime, Database, DatabaseBuilder, createDrive, initWasmSync, type RoleName } from '../../web/src/index.ts';
import { CMU_VRM_BONES, bvhToGltf, editGlbJson, readBvh } from './gltf-fixtures.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const MMDB = path.join(ROOT, 'wasm-core/target/opt/mmdb');
const BVH_FILE = path.resolve(ROOT, '../shared/mocap/cmu-asf/cmu_16_15.bvh');
const ROLES: RoleName[] = ['hips', 'left_foot', 'right_foot', 'left_toe', 'head', 'left_hand', 'right_hand'];

let take: ReturnType<typeof readBvh>;
let keys: number;
let tmp: string;
const files: Record<string, Uint8Array> = {};

beforeAll(async () => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  take = readBvh(BVH_FILE);
  keys = take.times.length;
  const half = Math.floor(keys / 2);
  files['walk.glb'] = await bvhToGltf(take, { clips: [['Walk', 0, keys]], dcc: true });
  files['clips.glb'] = await bvhToGltf(take, { clips: [['First', 0, half], ['Second', half, keys]], dcc: true });
  files['cubic.glb'] = await bvhToGltf(take, { clips: [['Walk', 0, keys]], interpolation: 'CUBICSPLINE' });
  files['walk.vrma'] = await bvhToGltf(take, { clips: [['Walk', 0, keys]], vrma: true });
  tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'mm-gltf-'));
  for (const [name, bytes] of Object.entries(files)) fs.writeFileSync(path.join(tmp, name), bytes);
  return () => fs.rmSync(tmp, { recursive: true, force: true });
}, 60_000);

function build(sources: [string, Uint8Array][], config: object = { mirror: false }): { db: Database; takes: string[] } {
  const builder = new DatabaseBuilder(config);
  try {
    const takes = sources.flatMap(([name, bytes]) => builder.addFile(name, bytes));
    return { db: Database.fromBytes(builder.build(), sources[0][0]), takes };
  } finally {
    builder.free();
  }
}

/** Largest distance between the two databases' joints of each role, over every frame (m). */
function largestGap(a: Database, b: Database): number {
  expect(a.numFrames).toBe(b.numFrames);
  let worst = 0;
  for (let f = 0; f < a.numFrames; f++) {
    const pa = a.worldPositions(f).slice();
    const pb = b.worldPositions(f);
    for (const role of ROLES) {
      const [ja, jb] = [a.roles.get(role)!, b.roles.get(role)!];
      worst = Math.max(worst, Math.hypot(pa[3 * ja] - pb[3 * jb], pa[3 * ja + 1] - pb[3 * jb + 1], pa[3 * ja + 2] - pb[3 * jb + 2]));
    }
  }
  return worst;
}

function walks(db: Database): number {
  const c = new CharacterRuntime(db);
  try {
    const input = createDrive();
    input.moveZ = 1;
    c.setDrive(input);
    const start = Array.from(c.root);
    for (let step = 0; step < 180; step++) c.update(1 / 60);
    return Math.hypot(c.root[0] - start[0], c.root[2] - start[2]);
  } finally {
    c.free();
  }
}

describe('glTF and VRM Animation in the page (WASM builder)', () => {
  it('a GLB export (Armature turned and scaled 0.01, bones with their own axes) builds the same database as its BVH; a character walks on it', () => {
    const bvh = build([['cmu_16_15.bvh', fs.readFileSync(BVH_FILE)]]);
    const glb = build([['walk.glb', files['walk.glb']]]);
    try {
      expect(glb.takes).toEqual(['walk.glb']);
      expect(glb.db.clips.map((c) => c.name)).toEqual(['walk']);
      for (const role of ROLES) expect(glb.db.roles.has(role), role).toBe(true);
      const gap = largestGap(bvh.db, glb.db);
      console.log(`walk.glb vs cmu_16_15.bvh: ${glb.db.numFrames} frames, largest role-joint gap ${(gap * 1000).toFixed(3)} mm`);
      expect(gap).toBeLessThan(0.002);
      const walked = walks(glb.db);
      console.log(`a character on walk.glb walked ${walked.toFixed(2)} m in 3 s`);
      expect(walked).toBeGreaterThan(2);
    } finally {
      bvh.db.release();
      glb.db.release();
    }
  });

  it('every animation of a GLB is a clip (file#clip); CUBICSPLINE keys are read', () => {
    const clips = build([['clips.glb', files['clips.glb']]]);
    const cubic = build([['cubic.glb', files['cubic.glb']]]);
    const bvh = build([['cmu_16_15.bvh', fs.readFileSync(BVH_FILE)]]);
    try {
      expect(clips.takes).toEqual(['clips.glb#First', 'clips.glb#Second']);
      expect(clips.db.clips.map((c) => c.name)).toEqual(['clips#First', 'clips#Second']);
      expect(largestGap(bvh.db, cubic.db)).toBeLessThan(0.002);
    } finally {
      for (const d of [clips, cubic, bvh]) d.db.release();
    }
  });

  it('a .vrma maps its bones by the VRM humanoid map (bone names say nothing) and builds the BVH\'s database; a character walks on it', () => {
    const bvh = build([['cmu_16_15.bvh', fs.readFileSync(BVH_FILE)]]);
    const vrma = build([['walk.vrma', files['walk.vrma']]]);
    try {
      expect(vrma.db.jointNames.filter((n) => n !== 'VirtualRoot').every((n) => /^Bone\d+$/.test(n))).toBe(true);
      // The map's bones are the database's roles.
      const boneOf = (cmu: string) => `Bone${take.bones.findIndex((b) => b.name === cmu)}`;
      const expected: [RoleName, string][] = [['hips', 'root'], ['left_foot', 'lfoot'], ['right_toe', 'rtoes'], ['head', 'head'], ['left_hand', 'lwrist'], ['chest', 'upperback']];
      for (const [role, cmu] of expected) {
        expect(CMU_VRM_BONES[cmu]).toBeDefined();
        expect(vrma.db.jointNames[vrma.db.roles.get(role)!], role).toBe(boneOf(cmu));
      }
      const gap = largestGap(bvh.db, vrma.db);
      console.log(`walk.vrma vs cmu_16_15.bvh: largest role-joint gap ${(gap * 1000).toFixed(3)} mm`);
      expect(gap).toBeLessThan(0.002);
      expect(walks(vrma.db)).toBeGreaterThan(2);
    } finally {
      bvh.db.release();
      vrma.db.release();
    }
  });

  it('BVH, GLB and VRMA takes build one database together (the other skeleton retargeted)', () => {
    const mixed = build([['walk.vrma', files['walk.vrma']], ['walk.glb', files['walk.glb']], ['cmu_16_15.bvh', fs.readFileSync(BVH_FILE)]]);
    try {
      // Clip names stay unique (the builder numbers a repeated one).
      expect(mixed.db.clips.map((c) => c.name)).toEqual(['walk', 'walk #2', 'cmu_16_15']);
    } finally {
      mixed.db.release();
    }
  });
});

/** Broken files: [file name, bytes, what the message must say]. */
function brokenFiles(): [string, Uint8Array, RegExp][] {
  const glb = files['walk.glb'];
  const edit = (f: (json: Record<string, unknown>) => void) => editGlbJson(glb, f);
  type Json = Record<string, unknown> & { accessors: Record<string, unknown>[]; animations: { samplers: Record<string, unknown>[]; channels: Record<string, unknown>[] }[]; nodes: Record<string, unknown>[] };
  return [
    ['truncated.glb', glb.subarray(0, 1000), /truncated\.glb: truncated GLB: its header says \d+ bytes, the file has 1000/],
    ['text.glb', new TextEncoder().encode('HIERARCHY\nROOT Hips'), /text\.glb: this is BVH text, not glTF/],
    ['garbage.vrma', new TextEncoder().encode('not a model at all'), /garbage\.vrma: not a glTF file/],
    ['bad-json.gltf', new TextEncoder().encode('{"asset": {"version": "2.0"}, "nodes": [}'), /bad-json\.gltf: glTF JSON: .*line 1 column/],
    ['old.gltf', new TextEncoder().encode('{"asset": {"version": "1.0"}}'), /old\.gltf: asset\.version 1\.0: only glTF 2\.0/],
    ['still.glb', edit((j) => delete j.animations), /still\.glb: no animations: the file has \d+ nodes/],
    ['external.gltf', new TextEncoder().encode(JSON.stringify({ asset: { version: '2.0' }, buffers: [{ uri: 'walk.bin', byteLength: 8 }], bufferViews: [{ buffer: 0, byteLength: 8 }], accessors: [{ bufferView: 0, componentType: 5126, count: 2, type: 'SCALAR' }, { bufferView: 0, componentType: 5126, count: 2, type: 'SCALAR' }], nodes: [{ name: 'a' }], animations: [{ samplers: [{ input: 0, output: 1 }], channels: [{ sampler: 0, target: { node: 0, path: 'translation' } }] }] })), /external\.gltf: .*buffer 0 is the external file walk\.bin: embed it/],
    ['short-accessor.glb', edit((j) => ((j as Json).accessors[0].count = 1e7)), /short-accessor\.glb: animation "?Walk"? \(0\): channel \d+ .*accessor 0\): 10000000 elements need \d+ bytes, its buffer view has \d+/],
    ['bad-node.glb', edit((j) => ((j as Json).animations[0].channels[3] = { sampler: 0, target: { node: 999, path: 'rotation' } })), /bad-node\.glb: animation "?Walk"? \(0\): channel 3's target node is 999, but there are \d+/],
    ['stretched.glb', edit((j) => ((j as Json).nodes[3].scale = [1, 2, 1])), /stretched\.glb: animation "?Walk"? \(0\): node .* has the scale \[1, 2, 1\]: a skeleton takes only a positive uniform scale/],
    ['bad-map.vrma', editGlbJson(files['walk.vrma'], (j) => (((j.extensions as Record<string, { humanoid: { humanBones: Record<string, { node: number }> } }>).VRMC_vrm_animation.humanoid.humanBones.leftFoot.node = 500))), /bad-map\.vrma: VRMC_vrm_animation humanoid: leftFoot → node is 500, but there are \d+/],
  ];
}

describe('broken glTF files: errors name the file and what is wrong', () => {
  it('in the page (WASM builder), when the file is added', () => {
    for (const [name, bytes, message] of brokenFiles()) {
      const builder = new DatabaseBuilder({});
      try {
        expect(() => builder.addFile(name, bytes), name).toThrow(message);
      } finally {
        builder.free();
      }
    }
  });

  it('a skeleton that is no humanoid is refused at the build, naming the take', () => {
    // Three bones in a row, animated: motion, but not a person.
    const chain = editGlbJson(files['walk.glb'], (j) => {
      const nodes = j.nodes as { name: string; children?: number[] }[];
      for (const n of nodes) delete n.children;
      nodes[0].children = [1];
      nodes[1].children = [2];
      nodes[2].children = [3];
      j.scenes = [{ nodes: [0] }];
      const anims = j.animations as { channels: { target: { node: number } }[] }[];
      anims[0].channels = anims[0].channels.filter((c) => c.target.node <= 3);
    });
    const builder = new DatabaseBuilder({});
    try {
      builder.addFile('chain.glb', chain);
      expect(() => builder.build()).toThrow(/chain\.glb: not a humanoid skeleton|chain\.glb: could not find/);
    } finally {
      builder.free();
    }
  });
});

describe('glTF and VRM Animation with the native CLI (mmdb build)', () => {
  const mmdb = (...args: string[]) => execFileSync(MMDB, args, { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });

  it('builds from a GLB with clips and from a .vrma; a character walks on each (mmdb quality)', () => {
    for (const file of ['clips.glb', 'walk.vrma']) {
      const out = path.join(tmp, `${file}.mmdb`);
      console.log(mmdb('build', path.join(tmp, file), '-o', out).trim());
      const info = JSON.parse(mmdb('inspect', out, '--json')) as { clips: { name: string }[]; num_frames: number };
      expect(info.clips.length).toBeGreaterThanOrEqual(file === 'clips.glb' ? 2 : 1);
      const quality = JSON.parse(mmdb('quality', out, '--json', '--seconds', '5')) as { script: string; travelled: number; mean_distance: number }[];
      const walk = quality.find((q) => q.script === 'straight walk')!;
      console.log(`${file}: straight walk travelled ${walk.travelled.toFixed(1)} m, mean distance to the input ${walk.mean_distance.toFixed(3)} m`);
      expect(walk.travelled).toBeGreaterThan(1);
      expect(walk.mean_distance).toBeLessThan(0.2);
    }
  });

  it('the same database natively and in the page', () => {
    const out = path.join(tmp, 'native.mmdb');
    mmdb('build', path.join(tmp, 'walk.vrma'), '-o', out, '--no-mirror');
    const native = Database.fromBytes(fs.readFileSync(out), 'native');
    const page = build([['walk.vrma', files['walk.vrma']]]);
    try {
      expect(largestGap(native, page.db)).toBeLessThan(1e-6);
    } finally {
      native.release();
      page.db.release();
    }
  });

  it('broken files: the CLI says which file and what is wrong', () => {
    for (const [name, bytes, message] of brokenFiles()) {
      const file = path.join(tmp, name);
      fs.writeFileSync(file, bytes);
      let stderr = '';
      try {
        mmdb('build', file, '-o', path.join(tmp, 'broken.mmdb'));
      } catch (e) {
        stderr = String((e as { stderr?: string }).stderr);
      }
      expect(stderr, name).toMatch(/^mmdb: error: /);
      expect(stderr.replace(`${tmp}/`, ''), name).toMatch(message);
    }
  });
});
