/**
 * `?emulate=1`: the iwer WebXR emulator (a Meta Quest 3 with Touch controllers) for desktops and
 * tests. `forceInstall` replaces Chromium's own `navigator.xr`, which exists even without a
 * headset. @iwer/devui (a panel to move the headset and controllers with mouse and keyboard)
 * is added for people, not for tests (`&devui=0`). Both load only when asked for.
 */
import type { XRDevice } from 'iwer';

export async function installEmulator(withDevUI: boolean): Promise<XRDevice> {
  const { XRDevice, metaQuest3 } = await import('iwer');
  const device = new XRDevice(metaQuest3);
  device.installRuntime({ forceInstall: true });
  if (withDevUI) {
    const { DevUI } = await import('@iwer/devui');
    device.installDevUI(DevUI);
  }
  return device;
}
