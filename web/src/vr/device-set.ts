/**
 * Which devices drive the avatar now (docs/vr.md, "Device sets"): the headset alone, with one or
 * two controllers, with tracked hands, or a mix — read each frame from the tracker state (a
 * controller asleep or frozen counts as absent: its arm hangs) and the sample's hand flags. The
 * VR page shows it; the avatar itself needs no switch, because an absent controller's hand
 * blends to a hanging pose and back (`TrackerState`), so a set can change at any frame.
 */
import { LEFT, RIGHT } from './tracker-sample.ts';
import { TRACKED } from './trackers.ts';

const NAMES = ['', 'controller', 'hand'] as const;

/** 0: absent, 1: a controller, 2: a hand — for the left and the right tracker. */
export function deviceKind(status: ArrayLike<number>, hand: ArrayLike<number>, t: number): 0 | 1 | 2 {
  return status[t] !== TRACKED ? 0 : hand[t] ? 2 : 1;
}

/** The name of each (left kind, right kind) pair, made once: naming the set every frame allocates nothing. */
const SET_NAMES: readonly string[] = [0, 1, 2].flatMap((l) =>
  [0, 1, 2].map((r) => {
    if (!l && !r) return 'headset only';
    if (l === r) return `headset + ${l === 1 ? '2 controllers' : 'hands'}`;
    return `headset + ${[l ? `left ${NAMES[l]}` : '', r ? `right ${NAMES[r]}` : ''].filter(Boolean).join(' + ')}`;
  }),
);

/** A short name of the set: "headset only", "headset + 2 controllers", "headset + hands", "headset + left controller", … */
export function deviceSetName(status: ArrayLike<number>, hand: ArrayLike<number>): string {
  return SET_NAMES[3 * deviceKind(status, hand, LEFT) + deviceKind(status, hand, RIGHT)];
}
