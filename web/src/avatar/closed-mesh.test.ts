import fs from 'node:fs';
import * as THREE from 'three';
import { beforeAll, describe, expect, it } from 'vitest';
import { isClosedMesh } from '../core/closed_mesh.ts';
import { initWasmSync } from '../core/wasm.ts';
import { cullHiddenBackFaces } from './closed-mesh.ts';

beforeAll(() => {
  initWasmSync(fs.readFileSync(new URL('../core/pkg/mmcore_bg.wasm', import.meta.url)));
});

const doubleSided = (geometry: THREE.BufferGeometry, options: THREE.MeshStandardMaterialParameters = {}) => new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({ side: THREE.DoubleSide, ...options }));

describe('closed meshes', () => {
  it('a box (faces split at its edges, as seams split a model) is closed; open, inside-out or broken surfaces are not', () => {
    expect(isClosedMesh(new THREE.BoxGeometry(1, 2, 3, 4, 5, 6))).toBe(true);
    expect(isClosedMesh(new THREE.BoxGeometry(1, 1, 1).toNonIndexed())).toBe(true);
    const quantized = new THREE.BoxGeometry(1, 1, 1, 2, 2, 2); // as a meshopt-compressed model stores it
    const f32 = quantized.getAttribute('position').array;
    quantized.setAttribute('position', new THREE.BufferAttribute(Int16Array.from(f32, (v) => Math.round(v * 32767)), 3, true));
    expect(isClosedMesh(quantized)).toBe(true);
    // Interleaved, four values a vertex: a quantized file pads its positions so.
    const padded = new THREE.BoxGeometry(1, 1, 1, 2, 2, 2);
    const xyz = padded.getAttribute('position').array;
    const xyzw = Int16Array.from({ length: (xyz.length / 3) * 4 }, (_, i) => (i % 4 === 3 ? 7 : Math.round(xyz[(i >> 2) * 3 + (i % 4)] * 32767)));
    padded.setAttribute('position', new THREE.InterleavedBufferAttribute(new THREE.InterleavedBuffer(xyzw, 4), 3, 0, true));
    expect(isClosedMesh(padded)).toBe(true);
    expect(isClosedMesh(new THREE.PlaneGeometry(1, 1, 4, 4))).toBe(false); // a card
    const inside = new THREE.BoxGeometry(1, 1, 1);
    const idx = inside.getIndex()!;
    for (let t = 0; t < idx.count; t += 3) {
      const b = idx.getX(t + 1);
      idx.setX(t + 1, idx.getX(t + 2));
      idx.setX(t + 2, b);
    }
    expect(isClosedMesh(inside)).toBe(false); // wound inward: its front faces are the inside
    const open = new THREE.BoxGeometry(1, 1, 1);
    open.setIndex(Array.from(open.getIndex()!.array).slice(6)); // one face missing
    expect(isClosedMesh(open)).toBe(false);
    const flipped = new THREE.BoxGeometry(1, 1, 1);
    const f = flipped.getIndex()!;
    const b = f.getX(1);
    f.setX(1, f.getX(2));
    f.setX(2, b); // one triangle wound the other way
    expect(isClosedMesh(flipped)).toBe(false);
  });

  it('only opaque double-sided materials whose every mesh is closed draw front faces only', () => {
    const root = new THREE.Group();
    const body = doubleSided(new THREE.BoxGeometry(1, 1, 1, 3, 3, 3));
    const card = doubleSided(new THREE.PlaneGeometry(1, 1));
    const shared = new THREE.MeshStandardMaterial({ side: THREE.DoubleSide });
    const closedToo = new THREE.Mesh(new THREE.BoxGeometry(1, 1, 1), shared);
    const openToo = new THREE.Mesh(new THREE.PlaneGeometry(1, 1), shared);
    const glass = doubleSided(new THREE.BoxGeometry(1, 1, 1), { transparent: true, opacity: 0.5 });
    const cutout = doubleSided(new THREE.BoxGeometry(1, 1, 1), { alphaTest: 0.5 });
    root.add(body, card, closedToo, openToo, glass, cutout);
    expect(cullHiddenBackFaces(root)).toBe(1);
    expect((body.material as THREE.Material).side).toBe(THREE.FrontSide);
    for (const m of [card, closedToo, glass, cutout]) expect((m.material as THREE.Material).side).toBe(THREE.DoubleSide);
  });

  it('a subdivided box of 10k vertices is closed (its time logged: it runs once per loaded model)', () => {
    const g = new THREE.BoxGeometry(1, 1, 1, 40, 40, 40);
    expect(g.getAttribute('position').count).toBeGreaterThan(10_000);
    for (let k = 0; k < 3; k++) {
      const t = performance.now();
      expect(isClosedMesh(g)).toBe(true);
      console.log(`isClosedMesh: ${g.getAttribute('position').count} vertices in ${(performance.now() - t).toFixed(1)} ms`);
    }
  });
});
