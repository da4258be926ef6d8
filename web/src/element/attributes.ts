/**
 * `<mm-avatar>`'s attribute values, checked. Attributes are typed by hand into other people's
 * pages, so every value the element does not understand gets a warning naming the attribute,
 * the value and what it accepts (and a sensible default), never an exception from inside the
 * element or a silently ignored typo.
 */

/** Words `controls` accepts. */
export const CONTROL_NAMES = ['keyboard', 'gamepad', 'path', 'none'] as const;
export type ControlName = (typeof CONTROL_NAMES)[number];

/** The longest attribute text a warning quotes (a pasted data: URL can be megabytes). */
const QUOTE_MAX = 80;

export function quote(value: string): string {
  return JSON.stringify(value.length > QUOTE_MAX ? `${value.slice(0, QUOTE_MAX)}…` : value);
}

/** `controls`: space-separated words; unknown ones are warned about and ignored. */
export function parseControls(value: string | null, warn: (message: string) => void): Set<ControlName> {
  const words = (value ?? 'keyboard gamepad').split(/\s+/).filter(Boolean);
  const out = new Set<ControlName>();
  for (const w of words) {
    if ((CONTROL_NAMES as readonly string[]).includes(w)) out.add(w as ControlName);
    else warn(`controls=${quote(value ?? '')}: unknown control ${quote(w)} ignored (use ${CONTROL_NAMES.join(', ')})`);
  }
  return out;
}

/** An attribute with a fixed set of values: `fallback` (with a warning) for anything else. */
export function parseChoice<T extends string>(
  name: string,
  value: string | null,
  allowed: readonly T[],
  fallback: T,
  warn: (message: string) => void,
): T {
  if (value === null) return fallback;
  const v = value.trim();
  if ((allowed as readonly string[]).includes(v)) return v as T;
  warn(`${name}=${quote(value)} is not one of ${allowed.join(', ')}; using ${fallback}`);
  return fallback;
}

/**
 * A URL attribute resolved against the page; `null` when unset or empty (the default asset).
 *
 * # Errors
 * A value that is not a URL (`http://[x`), or a scheme the element cannot fetch
 * (`javascript:`, `file:` from a web page).
 */
export function parseUrl(name: string, value: string | null, base: string): string | null {
  const v = value?.trim();
  if (!v) return null;
  let url: URL;
  try {
    url = new URL(v, base);
  } catch {
    throw new Error(`${name}=${quote(value ?? '')} is not a URL`);
  }
  if (!['http:', 'https:', 'blob:', 'data:'].includes(url.protocol)) {
    throw new Error(`${name}=${quote(value ?? '')}: the element fetches http(s), blob: and data: URLs, not ${url.protocol}`);
  }
  return url.href;
}

/**
 * `timeStep`: null (real time) or fixed seconds per frame in (0, 1]; anything else is refused
 * with a warning and leaves the previous value (NaN or a negative step would freeze or
 * reverse the element's clock; the runtime clamps long steps anyway).
 */
export function checkTimeStep(value: unknown, previous: number | null, warn: (message: string) => void): number | null {
  if (value === null || value === undefined) return null;
  if (typeof value === 'number' && Number.isFinite(value) && value > 0 && value <= 1) return value;
  warn(`timeStep ${String(value)} refused: null (real time) or seconds per frame in (0, 1]`);
  return previous;
}

/** Most updates one drawn frame may run (`stepsPerFrame`). */
const MAX_STEPS_PER_FRAME = 16;

/**
 * `stepsPerFrame`: a whole number of updates per drawn frame, 1 to 16; anything else is refused
 * with a warning and leaves the previous value.
 */
export function checkStepsPerFrame(value: unknown, previous: number, warn: (message: string) => void): number {
  if (Number.isInteger(value) && (value as number) >= 1 && (value as number) <= MAX_STEPS_PER_FRAME) return value as number;
  warn(`stepsPerFrame ${String(value)} refused: a whole number of updates per drawn frame, 1 to ${MAX_STEPS_PER_FRAME}`);
  return previous;
}
