/**
 * Orbit camera that follows a point on the floor: the user orbits/zooms freely, and both the
 * camera and its target translate with the followed point (smoothed by a half-life, snapping on
 * jumps such as clip boundaries).
 */
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const _delta = new THREE.Vector3();

export class FollowCamera {
  readonly controls: OrbitControls;
  /** Height of the orbit target above the followed point, m (about the hips). */
  targetHeight = 0.9;
  /** Smoothing half-life, s. */
  halflife = 0.12;
  /** A jump larger than this (m) is not smoothed. */
  snapDistance = 2.0;
  private readonly goal = new THREE.Vector3();
  private initialized = false;

  constructor(
    private readonly camera: THREE.PerspectiveCamera,
    dom: HTMLElement,
  ) {
    this.controls = new OrbitControls(camera, dom);
    this.controls.enableDamping = true;
    this.controls.dampingFactor = 0.15;
    this.controls.maxPolarAngle = Math.PI * 0.495;
    this.controls.minDistance = 0.5;
    this.controls.maxDistance = 30;
  }

  /** Follows floor point (x, z) over a time step of `dt` seconds. */
  follow(x: number, z: number, dt: number): void {
    this.goal.set(x, this.targetHeight, z);
    const target = this.controls.target;
    if (!this.initialized || target.distanceTo(this.goal) > this.snapDistance) {
      _delta.subVectors(this.goal, target);
      this.initialized = true;
    } else {
      const alpha = 1 - Math.pow(2, -dt / this.halflife);
      _delta.subVectors(this.goal, target).multiplyScalar(alpha);
    }
    target.add(_delta);
    this.camera.position.add(_delta);
    this.controls.update();
  }
}
