/**
 * Materials of the overlays (markers, trajectories, the skeleton): one shader program for every
 * flat-coloured overlay mesh and one for every overlay line. three.js compiles a program per
 * combination of opaque or transparent and single- or double-sided; drawn as four combinations
 * (and arrows opaque), the overlays cost five programs more than these two in a page's first
 * frame, ~10 ms each under a software GPU. Every overlay is transparent and double-sided here,
 * which at opacity 1 draws the same pixels (flat discs and rings, dots, cones, lines).
 */
import * as THREE from 'three';

/** A flat-coloured overlay mesh's material (transparent, double-sided). */
export function overlayMaterial(parameters: THREE.MeshBasicMaterialParameters): THREE.MeshBasicMaterial {
  // One pass: three.js draws a transparent double-sided material back faces first, then front
  // faces — two programs and two draws — unless told that one is enough (flat shapes).
  return new THREE.MeshBasicMaterial({ ...parameters, transparent: true, side: THREE.DoubleSide, forceSinglePass: true });
}

/** An overlay line's material (transparent). */
export function overlayLineMaterial(parameters: THREE.LineBasicMaterialParameters): THREE.LineBasicMaterial {
  return new THREE.LineBasicMaterial({ ...parameters, transparent: true });
}

/** three.js' arrow (a line and a cone) drawn with the overlays' programs. */
export function overlayArrow(direction: THREE.Vector3, length: number, color: number, headLength: number, headWidth: number): THREE.ArrowHelper {
  const arrow = new THREE.ArrowHelper(direction, new THREE.Vector3(), length, color, headLength, headWidth);
  for (const material of [arrow.line.material, arrow.cone.material] as THREE.Material[]) material.transparent = true;
  Object.assign(arrow.cone.material as THREE.Material, { side: THREE.DoubleSide, forceSinglePass: true });
  return arrow;
}
