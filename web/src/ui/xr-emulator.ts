/**
 * An emulated headset for a page without one (the VR page's `emulate=1`): iwer's Quest 3 over
 * Chromium's own `navigator.xr` (forceInstall), with `devUI` its panel for people. iwer loads on
 * demand. Returns the device (tests move it).
 */
export async function emulateQuest3(devUI: boolean): Promise<unknown> {
  const { XRDevice, metaQuest3 } = await import('iwer');
  const device = new XRDevice(metaQuest3);
  device.installRuntime({ forceInstall: true });
  if (devUI) device.installDevUI((await import('@iwer/devui')).DevUI);
  return device;
}
