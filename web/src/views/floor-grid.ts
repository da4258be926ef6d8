/**
 * Floor grid: 1 m cells, a brighter line every 5 m, recentred under the followed point (snapped
 * to 5 m, so lines stay fixed in the world).
 *
 * Lines are split into 1 m segments rather than drawn edge to edge like `THREE.GridHelper`:
 * software rasterizers (SwiftShader, used by headless test runs) drop whole lines that cross the
 * camera's near plane, which made the floor under the character disappear.
 */
import * as THREE from 'three';

const MAJOR_EVERY = 5;

export class FloorGrid {
  readonly object: THREE.LineSegments;

  /**
   * @param halfSize half the side of the grid, m (a multiple of 5)
   */
  constructor(halfSize = 20, minorColor = 0x353c43, majorColor = 0x56606a) {
    const n = halfSize * 2;
    // (n + 1) lines per direction, n unit segments each, 2 directions, 2 vertices per segment.
    const numVertices = (n + 1) * n * 2 * 2;
    const positions = new Float32Array(numVertices * 3);
    const colors = new Float32Array(numVertices * 3);
    const minor = new THREE.Color(minorColor);
    const major = new THREE.Color(majorColor);
    let v = 0;
    const push = (x: number, z: number, c: THREE.Color) => {
      positions[v * 3] = x;
      positions[v * 3 + 1] = 0;
      positions[v * 3 + 2] = z;
      colors[v * 3] = c.r;
      colors[v * 3 + 1] = c.g;
      colors[v * 3 + 2] = c.b;
      v++;
    };
    for (let i = -halfSize; i <= halfSize; i++) {
      const c = i % MAJOR_EVERY === 0 ? major : minor;
      for (let k = -halfSize; k < halfSize; k++) {
        push(i, k, c); // line along z at x = i
        push(i, k + 1, c);
        push(k, i, c); // line along x at z = i
        push(k + 1, i, c);
      }
    }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    geometry.setAttribute('color', new THREE.BufferAttribute(colors, 3));
    // Bounds known, not measured: three.js measures every vertex of a geometry without them in the
    // first frame that sorts it (~5-10 ms traced, its code still cold, while the first frame waits).
    geometry.boundingBox = new THREE.Box3(new THREE.Vector3(-halfSize, 0, -halfSize), new THREE.Vector3(halfSize, 0, halfSize));
    geometry.boundingSphere = new THREE.Sphere(new THREE.Vector3(), halfSize * Math.SQRT2);
    this.object = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ vertexColors: true }));
    this.object.frustumCulled = false;
  }

  /** Recentres the grid near floor point (x, z). */
  follow(x: number, z: number): void {
    this.object.position.set(Math.round(x / MAJOR_EVERY) * MAJOR_EVERY, 0, Math.round(z / MAJOR_EVERY) * MAJOR_EVERY);
  }
}
