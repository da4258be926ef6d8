/**
 * lil-gui helpers for the demo's panel: a choice whose options change, and a folder per group of
 * runtime settings (`RUNTIME_SETTINGS`: the panel is a loop over the list, not a copy of it).
 */
import type { Controller, GUI } from 'lil-gui';
import type { SettingInfo } from '../character/settings.ts';
import type { RuntimeSettings } from '../core/character.ts';

/**
 * Gives a choice new options and a value. lil-gui's `options()` makes a new controller without
 * the old one's callback: `onChange` is set again. Returns the new controller.
 */
export function setOptions(c: Controller, values: string[], value: string, onChange: (v: string) => void): Controller {
  return c.options(values).setValue(value).onChange(onChange);
}

/**
 * A closed folder per group under `parent`, a control per setting of `values`; a change calls
 * `onChange({ [key]: value })`.
 */
export function addSettingsFolders(
  parent: GUI,
  settings: readonly SettingInfo[],
  values: RuntimeSettings,
  onChange: (patch: RuntimeSettings) => void,
): void {
  const groups = new Map<string, GUI>();
  for (const s of settings) {
    if (!groups.has(s.group)) groups.set(s.group, parent.addFolder(s.group).close());
    const group = groups.get(s.group)!;
    const c = s.range ? group.add(values, s.key, ...s.range) : group.add(values, s.key, s.options);
    c.name(s.label).onChange((v: unknown) => onChange({ [s.key]: v }));
  }
}
