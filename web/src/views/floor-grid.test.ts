import * as THREE from 'three';
import { describe, expect, it } from 'vitest';
import { FloorGrid } from './floor-grid.ts';

describe('FloorGrid', () => {
  it('comes with bounds that hold every vertex (three.js would measure them in the first frame)', () => {
    for (const half of [5, 20]) {
      const geometry = new FloorGrid(half).object.geometry;
      const { boundingBox: box, boundingSphere: sphere } = geometry;
      expect(box).not.toBeNull();
      expect(sphere).not.toBeNull();
      const p = new THREE.Vector3();
      const position = geometry.getAttribute('position');
      for (let i = 0; i < position.count; i++) {
        p.fromBufferAttribute(position, i);
        expect(box!.containsPoint(p)).toBe(true);
        expect(sphere!.center.distanceTo(p)).toBeLessThanOrEqual(sphere!.radius + 1e-9);
      }
      // Not loose either: the measured sphere is the same.
      const measured = new THREE.Sphere();
      new THREE.Box3().setFromBufferAttribute(position as THREE.BufferAttribute).getBoundingSphere(measured);
      expect(sphere!.radius).toBeCloseTo(measured.radius, 9);
    }
  });
});
