/**
 * Keeps a retargeted avatar's planted feet on the floor. Retargeting maps a planted source toe
 * to the avatar's standing toe height exactly only when the two legs have the same proportions;
 * otherwise the avatar floats or sinks a few centimetres in stance. This learns the residual
 * as a vertical hips offset from the feet in contact: each frame it moves the offset toward
 * putting the lower planted toe at its standing height (exponentially, so a change of contacts
 * never pops), and holds it while no foot is planted. The avatar's own leg proportions are
 * kept; only its height over the floor changes.
 */
/** Largest toe height error (m) one update acts on. */
const MAX_RESIDUAL = 0.03;

export class Grounding {
  /** Metres to add to the avatar's hips height. */
  offset = 0;

  /**
   * `standingToeHeight`: the avatar's toe height standing on the floor (its rest pose);
   * `halflife`: seconds for the offset to halve its error.
   */
  constructor(
    readonly standingToeHeight: number,
    readonly halflife = 0.1,
  ) {}

  /**
   * Call after posing the avatar with the current `offset`: toe heights (m; NaN when the avatar
   * has no toe on that side) and contact bits (1 left, 2 right). Returns the new offset.
   */
  update(leftToe: number, rightToe: number, contacts: number, dt: number): number {
    let error = Infinity;
    const any = (contacts & 1 && Number.isFinite(leftToe)) || (contacts & 2 && Number.isFinite(rightToe));
    if (contacts & 1 && Number.isFinite(leftToe)) error = leftToe - this.standingToeHeight;
    if (contacts & 2 && Number.isFinite(rightToe)) error = Math.min(error, rightToe - this.standingToeHeight);
    // Only the residual is learnt: a toe far off the floor is a transient (a lock still blending
    // in after a transition), and following it would push the other foot through the floor.
    error = Math.max(-MAX_RESIDUAL, Math.min(MAX_RESIDUAL, error));
    if (any && dt > 0) this.offset -= error * (1 - 2 ** (-dt / this.halflife));
    return this.offset;
  }
}
