import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { RawDatabase } from '../../web/src/core/raw.ts';
import { wasmMemory } from '../../web/src/core/wasm.ts';
import { Database, DatabaseBuilder, ROLE_NAMES, initWasmSync } from '../../web/src/index.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const MMDB = path.join(ROOT, 'wasm-core/target/opt/mmdb');
const DB_PATH = path.join(ROOT, 'public/databases/locomotion.mmdb');
const BVH = path.resolve(ROOT, '../shared/mocap/cmu-asf/cmu_16_15.bvh');

function inspect(file: string): Record<string, unknown> {
  return JSON.parse(execFileSync(MMDB, ['inspect', file, '--json'], { encoding: 'utf8' })) as Record<string, unknown>;
}

beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
});

describe('Database (WASM in Node)', () => {
  it('loads locomotion.mmdb with the frame count the native CLI reports', () => {
    const db = Database.fromBytes(fs.readFileSync(DB_PATH));
    try {
      const cli = inspect(DB_PATH);
      expect(db.numFrames).toBe(cli['num_frames']);
      expect(db.numFrames).toBeGreaterThan(0);
      expect(db.fps).toBeCloseTo(cli['fps'] as number, 5);
      expect(db.jointParents[0]).toBe(-1);
      for (let j = 1; j < db.numJoints; j++) expect(db.jointParents[j]).toBeLessThan(j);
      // Clips tile [0, F).
      expect(db.clips.length).toBe((cli['clips'] as unknown[]).length);
      expect(db.clips[0].start).toBe(0);
      expect(db.clips[db.clips.length - 1].end).toBe(db.numFrames);
      expect(db.clipAt(db.numFrames - 1)).toBe(db.clips.length - 1);
      // The roles are the runtime's one vocabulary, read from the file's site table.
      for (const role of ['hips', 'left_foot', 'right_toe', 'head', 'left_hand', 'chest'] as const) expect(db.roles.has(role), role).toBe(true);
      for (const role of db.roles.keys()) expect(ROLE_NAMES).toContain(role);
      expect(db.toeHeight).toBeGreaterThan(0);
    } finally {
      db.release();
    }
  });

  it('exposes zero-copy views of the right lengths', () => {
    const db = Database.fromBytes(fs.readFileSync(DB_PATH));
    try {
      const F = db.numFrames;
      const J = db.numJoints;
      expect(db.localPositions.length).toBe(F * J * 3);
      expect(db.localRotations.length).toBe(F * J * 4);
      expect(db.contacts.length).toBe(F * 2);
      expect(db.featureMatrix.length).toBe(F * db.numFeatures);
      expect(db.localPositions.buffer).toBe(wasmMemory().buffer);
      // Contacts are 0/1 and some frame has a foot down.
      expect(db.contacts.every((c) => c === 0 || c === 1)).toBe(true);
      expect(db.contacts.some((c) => c === 1)).toBe(true);
      // Rotations are unit quaternions.
      const q = db.localRotations;
      for (let i = 0; i < Math.min(q.length, 4000); i += 4) {
        expect(Math.hypot(q[i], q[i + 1], q[i + 2], q[i + 3])).toBeCloseTo(1, 3);
      }
    } finally {
      db.release();
    }
  });

  it('world positions of frame 0: virtual root on the floor, head above 1.3 m', () => {
    const db = Database.fromBytes(fs.readFileSync(DB_PATH));
    try {
      const pos = db.worldPositions(0);
      expect(pos.length).toBe(db.numJoints * 3);
      expect(pos[1]).toBeCloseTo(0, 5); // joint 0, y
      const head = db.roles.get('head')!;
      expect(head).toBeGreaterThan(0);
      expect(pos[head * 3 + 1]).toBeGreaterThan(1.3);
      // Feet near the floor.
      const minY = Math.min(...Array.from({ length: db.numJoints - 1 }, (_, j) => pos[(j + 1) * 3 + 1]));
      expect(minY).toBeGreaterThan(-0.05);
      expect(minY).toBeLessThan(0.2);
      // The same view is reused: no allocation per call.
      const again = db.worldPositions(1);
      expect(again).toBe(pos);
      expect(db.worldRotations().length).toBe(db.numJoints * 4);
    } finally {
      db.release();
    }
  });

  it('recreates views after WASM memory grows (old buffer detached)', () => {
    const db = Database.fromBytes(fs.readFileSync(DB_PATH));
    try {
      const before = db.localPositions;
      const first = Array.from(before.subarray(0, 12));
      expect(db.localPositions).toBe(before); // cached while the buffer is unchanged
      wasmMemory().grow(1);
      expect(before.length).toBe(0); // detached
      const after = db.localPositions;
      expect(after === before).toBe(false);
      expect(Array.from(after.subarray(0, 12))).toEqual(first);
      expect(db.worldPositions(0).length).toBe(db.numJoints * 3);
    } finally {
      db.release();
    }
  });

  it('rejects a corrupt file with a checksum error', () => {
    const bytes = new Uint8Array(fs.readFileSync(DB_PATH));
    bytes[Math.floor(bytes.length / 2)] ^= 0xff;
    expect(() => Database.fromBytes(bytes)).toThrow(/checksum/i);
    expect(() => new RawDatabase(bytes)).toThrow(/checksum/i);
  });

  it('rejects a truncated file', () => {
    const bytes = new Uint8Array(fs.readFileSync(DB_PATH)).subarray(0, 20);
    expect(() => Database.fromBytes(bytes)).toThrow();
  });
});

describe('DatabaseBuilder (WASM in Node)', () => {
  it('builds a BVH to the same frame count as the native CLI', () => {
    const builder = new DatabaseBuilder({});
    let bytes: Uint8Array;
    try {
      builder.addBvh(path.basename(BVH), fs.readFileSync(BVH));
      bytes = builder.build();
      expect(Array.isArray(builder.warnings())).toBe(true);
    } finally {
      builder.free();
    }
    const db = Database.fromBytes(bytes);
    try {
      // Native build of the same file with the same (default) options.
      const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'mmdb-test-'));
      try {
        const config = path.join(dir, 'one.json');
        fs.writeFileSync(config, JSON.stringify({ clips: [{ file: BVH }] }));
        const out = path.join(dir, 'one.mmdb');
        execFileSync(MMDB, ['build', '--config', config, '-o', out], { stdio: 'pipe' });
        const cli = inspect(out);
        expect(db.numFrames).toBe(cli['num_frames']);
        expect(db.numJoints).toBe(cli['num_joints']);
        expect(db.numFrames).toBeGreaterThan(0);
      } finally {
        fs.rmSync(dir, { recursive: true, force: true });
      }
    } finally {
      db.release();
    }
  });

  it('reports a bad BVH with a file:line message', () => {
    const builder = new DatabaseBuilder({});
    try {
      const bad = new TextEncoder().encode('HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 zero\n');
      expect(() => builder.addBvh('bad.bvh', bad)).toThrow(/bad\.bvh:\d+/);
    } finally {
      builder.free();
    }
  });
});

describe('first part (PART): a character starts on it and moves to the whole', () => {
  const VR = path.join(ROOT, 'public/databases/vr.mmdb');

  it('names its whole beside it, loads it after its first frames over HTTP and moves there on the same frame', async () => {
    const { Character, loadDatabase } = await import('../../web/src/index.ts');
    const http = await import('node:http');
    // The site's files on loopback: the character fetches the whole as a page does.
    let redirect = { from: '', to: '' };
    const hits = new Map<string, number>();
    const server = http.createServer((req, res) => {
      const asked = decodeURIComponent(new URL(req.url ?? '/', 'http://x').pathname);
      hits.set(asked, (hits.get(asked) ?? 0) + 1);
      const file = path.join(ROOT, 'public', asked === redirect.from ? redirect.to : asked);
      if (!file.startsWith(path.join(ROOT, 'public')) || !fs.existsSync(file)) return void res.writeHead(404).end();
      res.writeHead(200, { 'content-type': 'application/octet-stream' }).end(fs.readFileSync(file));
    });
    await new Promise<void>((r) => server.listen(0, '127.0.0.1', r));
    const base = `http://127.0.0.1:${(server.address() as { port: number }).port}/databases/`;
    try {
      const part = await loadDatabase(`${base}locomotion.first.mmdb?v=1`);
      expect(part.wholeUrl).toBe(`${base}locomotion.mmdb`);
      const whole = Database.fromBytes(fs.readFileSync(DB_PATH), 'locomotion.mmdb');
      const other = Database.fromBytes(fs.readFileSync(VR), 'vr.mmdb');
      expect(whole.wholeUrl).toBeNull();
      expect(part.numFrames).toBeLessThan(whole.numFrames / 5);
      expect([part.isPartOf(whole), part.isPartOf(other), whole.isPartOf(part)]).toEqual([true, false, false]);
      const c = new Character(part);
      part.release(); // the character holds it
      expect(() => c.runtime.enterWhole(other)).toThrow(/first part of locomotion\.mmdb .* not of the one given/);
      c.setMove(0, 1);
      for (let i = 0; i < 90; i++) c.update(1 / 60); // the second update starts the whole's download
      const [frame, j, partRotations] = [c.runtime.frame, part.numJoints, part.localRotations.slice()];
      const [before, root] = [Array.from(c.runtime.worldPositions), { ...c.root }];
      const loaded = await c.whole(); // it moves as soon as the whole is here, between updates
      expect([loaded.numFrames, c.database, part.isFreed]).toEqual([whole.numFrames, loaded, true]);
      const now = c.runtime.frame;
      expect(now).not.toBe(frame);
      const rotations = (r: Float32Array, f: number) => Array.from(r.subarray(f * j * 4, (f + 1) * j * 4));
      expect(rotations(loaded.localRotations, now)).toEqual(rotations(partRotations, frame));
      c.pose(0);
      expect(Array.from(c.runtime.worldPositions)).toEqual(before);
      expect(c.root).toEqual(root);
      for (let i = 0; i < 60; i++) c.update(1 / 60); // and walks on in the whole
      expect(Math.hypot(c.root.x - root.x, c.root.z - root.z)).toBeGreaterThan(0.5);
      expect(() => c.runtime.enterWhole(loaded)).toThrow(/not a first part/);
      c.dispose();

      // A whole that is missing, or of another build, leaves the character on its part, saying so.
      const lone = Database.fromBytes(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.first.mmdb')), `${base}nowhere/locomotion.first.mmdb`);
      const stays = new Character(lone);
      await expect(stays.whole()).rejects.toThrow(/is a first part; its whole did not load, so the character keeps the part: .*nowhere\/locomotion\.mmdb: HTTP 404/);
      expect(stays.database).toBe(lone);
      await expect(stays.whole()).rejects.toThrow(/HTTP 404/);
      expect(hits.get('/databases/nowhere/locomotion.mmdb')).toBe(2); // tried again, not a kept failure
      const renamed = Database.fromBytes(fs.readFileSync(path.join(ROOT, 'public/databases/vr.first.mmdb')), `${base}vr.first.mmdb`);
      const wrong = new Character(renamed);
      redirect = { from: '/databases/vr.mmdb', to: 'databases/locomotion.mmdb' }; // another file under the whole's name
      await expect(wrong.whole()).rejects.toThrow(/vr\.mmdb is not the database .* is the first part of \(another build\?\)/);
      expect(wrong.database).toBe(renamed);
      for (const x of [stays, wrong]) x.update(1 / 60); // and they play on
      [stays, wrong, lone, renamed, whole, other].forEach((x) => ('dispose' in x ? x.dispose() : x.release()));
    } finally {
      server.close();
    }
  });
});
