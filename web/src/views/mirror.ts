import * as THREE from 'three';
import { Reflector } from 'three/addons/objects/Reflector.js';

/**
 * A wall mirror, 1.6 × 2.2 m, facing the start position from 3 m ahead (−Z); its texture
 * `textureWidth` px wide (clamped to 64–2048), 1.375 times that high.
 *
 * It shows from its scene's second render on. The reflection draws the scene into a texture,
 * whose colours are linear, not the canvas' sRGB: each material drawn there needs a second
 * shader program (three.js keys programs by output colour space), compiled at its first draw —
 * the avatar's three and the grid's, ~0.1 s of a first frame under a software GPU. The first
 * frame comes without them; the second pays.
 */
export function createMirror(textureWidth: number): Reflector {
  const width = Math.max(64, Math.min(2048, textureWidth));
  const options = { textureWidth: width, textureHeight: Math.round(width * 1.375), color: 0xb8c0c8, multisample: 0 };
  const mirror = new Reflector(new THREE.PlaneGeometry(1.6, 2.2), options);
  mirror.position.set(0, 1.1, -3);
  mirror.visible = false;
  mirror.addEventListener('added', () => {
    const scene = mirror.parent;
    if (!scene || mirror.visible) return;
    // Only a scene hears of its renders (a group is never drawn itself): elsewhere, shown at once.
    if (!(scene as THREE.Scene).isScene) return void (mirror.visible = true);
    const after = scene.onAfterRender;
    scene.onAfterRender = function (...args) {
      scene.onAfterRender = after;
      after.apply(this, args);
      mirror.visible = true;
    };
  });
  return mirror;
}
