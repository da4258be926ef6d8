/**
 * A person's name floating above their avatar in a shared room: a three.js sprite (it faces the
 * camera, in the page and in a headset alike) drawn once on a canvas. The text is a remote
 * member's name — already screened by the protocol (no control or bidi-override characters) —
 * and is drawn as text, never parsed as markup.
 */
import * as THREE from 'three';

const WIDTH = 512;
const HEIGHT = 96;

export class NameLabel {
  readonly object: THREE.Sprite;
  /** Null where there is no canvas (Node: tests and tools), the label then being blank. */
  private readonly canvas: HTMLCanvasElement | OffscreenCanvas | null;
  private readonly texture: THREE.CanvasTexture<HTMLCanvasElement | OffscreenCanvas> | null;

  /** `height`: the label's height in metres (its width follows the canvas' aspect). */
  constructor(text: string, height = 0.12) {
    this.canvas =
      typeof document !== 'undefined'
        ? Object.assign(document.createElement('canvas'), { width: WIDTH, height: HEIGHT })
        : typeof OffscreenCanvas !== 'undefined'
          ? new OffscreenCanvas(WIDTH, HEIGHT)
          : null;
    this.texture = this.canvas ? new THREE.CanvasTexture(this.canvas) : null;
    if (this.texture) this.texture.colorSpace = THREE.SRGBColorSpace;
    const material = new THREE.SpriteMaterial({ map: this.texture, transparent: true, depthWrite: false });
    this.object = new THREE.Sprite(material);
    this.object.name = 'mm-name-label';
    this.object.scale.set((height * WIDTH) / HEIGHT, height, 1);
    this.object.renderOrder = 10;
    this.setText(text);
  }

  /** The text shown. */
  text = '';

  setText(text: string): void {
    this.text = text;
    const g = this.canvas?.getContext('2d') as CanvasRenderingContext2D | null | undefined;
    if (!g || !this.texture) return;
    g.clearRect(0, 0, WIDTH, HEIGHT);
    g.font = '600 52px system-ui, sans-serif';
    const width = Math.min(WIDTH - 8, g.measureText(text).width + 40);
    g.fillStyle = 'rgba(20, 23, 28, 0.72)';
    g.beginPath();
    g.roundRect((WIDTH - width) / 2, 8, width, HEIGHT - 16, 30);
    g.fill();
    g.fillStyle = '#f2f4f7';
    g.textAlign = 'center';
    g.textBaseline = 'middle';
    g.fillText(text, WIDTH / 2, HEIGHT / 2 + 2, WIDTH - 48);
    this.texture.needsUpdate = true;
  }

  dispose(): void {
    this.object.removeFromParent();
    this.texture?.dispose();
    this.object.material.dispose();
  }
}
