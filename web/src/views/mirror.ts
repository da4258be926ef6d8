import * as THREE from 'three';
import { Reflector } from 'three/addons/objects/Reflector.js';

/**
 * A wall mirror, 1.6 × 2.2 m, facing the start position from 3 m ahead (−Z); its texture
 * `textureWidth` px wide (clamped to 64–2048), 1.375 times that high.
 */
export function createMirror(textureWidth: number): Reflector {
  const width = Math.max(64, Math.min(2048, textureWidth));
  const options = { textureWidth: width, textureHeight: Math.round(width * 1.375), color: 0xb8c0c8, multisample: 0 };
  const mirror = new Reflector(new THREE.PlaneGeometry(1.6, 2.2), options);
  mirror.position.set(0, 1.1, -3);
  return mirror;
}
