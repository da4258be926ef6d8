import * as THREE from 'three';
import { TRACKED, type TrackerState } from '../vr/trackers.ts';
import { LEFT, RIGHT } from '../vr/tracker-sample.ts';

/** Boxes at the controller grips (blue left, orange right), shown while their controller is tracked. */
export class ControllerMarkers {
  /** The two boxes, left then right: add them to the scene. */
  readonly meshes = [0x4fa3ff, 0xff7a4f].map((color) => {
    const material = new THREE.MeshStandardMaterial({ color, roughness: 0.6 });
    return new THREE.Mesh(new THREE.BoxGeometry(0.04, 0.04, 0.12), material);
  });

  /** Moves the boxes to the trackers' grip poses (every frame: no array or closure made). */
  update(trackers: TrackerState): void {
    for (let k = 0; k < 2; k++) {
      const view = k ? trackers.right : trackers.left;
      const marker = this.meshes[k];
      marker.position.fromArray(view.position);
      marker.quaternion.fromArray(view.rotation);
      marker.visible = trackers.status[k ? RIGHT : LEFT] === TRACKED;
    }
  }
}
