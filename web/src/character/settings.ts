/**
 * The runtime settings a user interface can offer (docs/runtime.md has them all): name, group,
 * label and range, so a panel is a loop over this list and cannot drift from the runtime's
 * names (`CharacterSettings` in Rust).
 */
export interface SettingInfo {
  key: string;
  group: 'Search' | 'Blending' | 'Following the controller' | 'Feet';
  label: string;
  /** Numeric range and step; absent for booleans and choices. */
  range?: readonly [number, number, number];
  /** Allowed values of a choice. */
  options?: readonly string[];
}

export const RUNTIME_SETTINGS: readonly SettingInfo[] = [
  { key: 'beta_pose', group: 'Search', label: 'β_q (pose: quality)', range: [0, 5, 0.05] },
  { key: 'beta_trajectory', group: 'Search', label: 'β_r (trajectory: response)', range: [0, 5, 0.05] },
  { key: 'search_interval', group: 'Search', label: 'interval (frames)', range: [1, 60, 1] },
  { key: 'search_method', group: 'Search', label: 'method', options: ['aabb', 'simd', 'scalar'] },
  { key: 'inertialize', group: 'Blending', label: 'inertialize' },
  { key: 'inertialization_halflife', group: 'Blending', label: 'half-life (s)', range: [0.01, 0.5, 0.01] },
  { key: 'playback_speed', group: 'Blending', label: 'playback speed', range: [0.1, 2, 0.05] },
  { key: 'adjustment', group: 'Following the controller', label: 'adjustment' },
  { key: 'clamping', group: 'Following the controller', label: 'clamping' },
  { key: 'clamp_distance', group: 'Following the controller', label: 'α (m)', range: [0.02, 0.5, 0.01] },
  { key: 'clamp_angle', group: 'Following the controller', label: 'max yaw gap (rad)', range: [0.05, Math.PI, 0.01] },
  { key: 'foot_lock', group: 'Feet', label: 'foot lock' },
];
