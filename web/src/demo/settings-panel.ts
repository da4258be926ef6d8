/**
 * The lil-gui panel of the demo: every motion-matching knob, applied live through
 * `Crowd.setSettings` (the Rust `CharacterSettings` names, so the two cannot drift apart). The
 * crowd is looked up on every change, so the panel survives database switches.
 */
import GUI from 'lil-gui';
import { type Crowd } from '../core/crowd.ts';

type Settings = Record<string, number | boolean | string>;

export function createSettingsPanel(gui: GUI, crowd: () => Crowd): Settings {
  const values = crowd().settings(0) as Settings;
  const apply = (key: string) => (value: unknown) => crowd().setSettings({ [key]: value });
  const search = gui.addFolder('Search');
  search.add(values, 'beta_pose', 0, 5, 0.05).name('β_q (pose: quality)').onChange(apply('beta_pose'));
  search.add(values, 'beta_trajectory', 0, 5, 0.05).name('β_r (trajectory: response)').onChange(apply('beta_trajectory'));
  search.add(values, 'search_interval', 1, 60, 1).name('interval (frames)').onChange(apply('search_interval'));
  search.add(values, 'search_method', ['aabb', 'simd', 'scalar']).name('method').onChange(apply('search_method'));
  const blend = gui.addFolder('Blending');
  blend.add(values, 'inertialize').onChange(apply('inertialize'));
  blend.add(values, 'inertialization_halflife', 0.01, 0.5, 0.01).name('half-life (s)').onChange(apply('inertialization_halflife'));
  blend.add(values, 'playback_speed', 0.1, 2, 0.05).name('playback speed').onChange(apply('playback_speed'));
  const follow = gui.addFolder('Following the controller');
  follow.add(values, 'adjustment').onChange(apply('adjustment'));
  follow.add(values, 'clamping').onChange(apply('clamping'));
  follow.add(values, 'clamp_distance', 0.02, 0.5, 0.01).name('α (m)').onChange(apply('clamp_distance'));
  follow.add(values, 'clamp_angle', 0.05, Math.PI, 0.01).name('max yaw gap (rad)').onChange(apply('clamp_angle'));
  const feet = gui.addFolder('Feet');
  feet.add(values, 'foot_lock').name('foot lock').onChange(apply('foot_lock'));
  for (const f of [blend, follow, feet]) f.close();
  return values;
}
