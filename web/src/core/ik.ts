/**
 * `TwoBoneIk`: the runtime's one two-bone IK (wasm-core/src/runtime/ik.rs, law of cosines with an exact
 * pole plane) for the avatar's arms. Inputs and outputs are zero-copy views; nothing allocates.
 */
import { RawTwoBoneIk } from './raw.ts';
import { ViewCache } from './view-cache.ts';
import { freeRaw, wasmMemory } from './wasm.ts';

export interface Vec3Like {
  x: number;
  y: number;
  z: number;
}

export interface QuatLike {
  set(x: number, y: number, z: number, w: number): unknown;
}

export class TwoBoneIk {
  private readonly raw = new RawTwoBoneIk();
  private readonly input = new ViewCache(Float32Array, 15);
  private readonly output = new ViewCache(Float32Array, 8);

  /**
   * Rotation deltas (world) of the root joint (`ra`) and middle joint (`rb`) that bring the end
   * joint `c` to `target`, bending toward `pole`: new world rotations are `ra · old` and
   * `rb · old`. Out of reach the chain points at the target; `eps` keeps it off straight.
   */
  solve(a: Vec3Like, b: Vec3Like, c: Vec3Like, target: Vec3Like, pole: Vec3Like, eps: number, ra: QuatLike, rb: QuatLike): void {
    const v = this.input.get(wasmMemory(), this.raw.input_ptr());
    const put = (k: number, p: Vec3Like) => {
      v[3 * k] = p.x;
      v[3 * k + 1] = p.y;
      v[3 * k + 2] = p.z;
    };
    put(0, a);
    put(1, b);
    put(2, c);
    put(3, target);
    put(4, pole);
    this.raw.solve(eps);
    const o = this.output.get(wasmMemory(), this.raw.output_ptr());
    ra.set(o[0], o[1], o[2], o[3]);
    rb.set(o[4], o[5], o[6], o[7]);
  }

  free(): void {
    freeRaw(this.raw, 'rawtwoboneik');
  }
}
