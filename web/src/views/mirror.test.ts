import * as THREE from 'three';
import { describe, expect, it } from 'vitest';
import { createMirror } from './mirror.ts';

describe('createMirror', () => {
  it('shows from its scene\'s second render on (its programs are not compiled in the first frame)', () => {
    const scene = new THREE.Scene();
    let renders = 0;
    scene.onAfterRender = () => void renders++;
    const mirror = createMirror(64);
    scene.add(mirror);
    expect(mirror.visible).toBe(false);
    // What WebGLRenderer.render calls at the end of a render of the scene.
    const args = [null, scene, new THREE.PerspectiveCamera()] as unknown as Parameters<THREE.Scene['onAfterRender']>;
    scene.onAfterRender(...args);
    expect(mirror.visible).toBe(true);
    expect(renders).toBe(1); // the scene's own callback still runs, and is back in place
    scene.onAfterRender(...args);
    expect(renders).toBe(2);
    mirror.visible = false; // a page may hide it later: it stays hidden
    scene.onAfterRender(...args);
    expect(mirror.visible).toBe(false);
  });

  it('under a group (never rendered itself) shows at once', () => {
    const group = new THREE.Group();
    const mirror = createMirror(64);
    group.add(mirror);
    expect(mirror.visible).toBe(true);
  });
});
