/** Which joints belong to each foot, for coloring contacts. */
import type { Database } from '../core/database.ts';

export interface FootJoints {
  left: number[];
  right: number[];
}

/**
 * Uses the database's named sites (`left_foot`, `left_toe`, ...) when the inspect JSON lists
 * them, otherwise guesses from joint names (foot/ankle/toe with a left/right marker).
 */
export function findFootJoints(db: Pick<Database, 'sites' | 'jointNames'>): FootJoints {
  const left = new Set<number>();
  const right = new Set<number>();
  for (const site of db.sites()) {
    if (site.joint <= 0) continue;
    if (site.name === 'left_foot' || site.name === 'left_toe') left.add(site.joint);
    if (site.name === 'right_foot' || site.name === 'right_toe') right.add(site.joint);
  }
  if (left.size === 0 && right.size === 0) {
    db.jointNames.forEach((name, j) => {
      if (j === 0 || !/foot|ankle|toe/i.test(name)) return;
      if (/left|^l(?=[A-Z_.])|^l_|_l$|\.l$/i.test(name) || /^L/.test(name)) left.add(j);
      else if (/right|^r(?=[A-Z_.])|^r_|_r$|\.r$/i.test(name) || /^R/.test(name)) right.add(j);
    });
  }
  return { left: [...left], right: [...right] };
}
