/** The virtual root (joint 0) drawn on the floor: a disc and an arrow along its facing (+Z). */
import * as THREE from 'three';
import { overlayArrow, overlayMaterial } from './overlay-materials.ts';

export class RootMarker {
  readonly object = new THREE.Group();

  constructor() {
    const disc = new THREE.Mesh(
      new THREE.CircleGeometry(0.22, 40),
      overlayMaterial({ color: 0x3fd68a, opacity: 0.35, depthWrite: false }),
    );
    disc.rotation.x = -Math.PI / 2;
    const ring = new THREE.Mesh(
      new THREE.RingGeometry(0.21, 0.235, 40),
      overlayMaterial({ color: 0x3fd68a }),
    );
    ring.rotation.x = -Math.PI / 2;
    // Facing arrow along local +Z (character forward).
    const arrow = overlayArrow(new THREE.Vector3(0, 0, 1), 0.55, 0x3fd68a, 0.14, 0.09);
    this.object.add(disc, ring, arrow);
    this.object.position.y = 0.004; // just above the grid, no z-fighting
  }

  /**
   * @param worldPositions `J×3`; joint 0 is read
   * @param worldRotations `J×4` `(x, y, z, w)`; joint 0 is read
   */
  update(worldPositions: Float32Array, worldRotations: Float32Array): void {
    this.object.position.set(worldPositions[0], worldPositions[1] + 0.004, worldPositions[2]);
    this.object.quaternion.set(worldRotations[0], worldRotations[1], worldRotations[2], worldRotations[3]);
  }
}
