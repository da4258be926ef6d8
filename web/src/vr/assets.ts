/**
 * The VR entry's shipped assets: the orientation models (only this entry names them, so a desktop
 * app's bundler never copies them; assets.ts explains the literal URLs) and the VR page's
 * database (not in the package: the site serves it, `setAssetBase` finds it elsewhere).
 */
import { PACKAGE, assetUrl, shippedAssetUrl } from '../assets.ts';

/** The VR page's database (docs/database.md, `vr.json`): slow walks, steps, gestures, idle. */
export const DEFAULT_VR_DATABASE = 'databases/vr.mmdb';
/** The orientation model for the headset and both controllers (docs/orientation-model.md). */
export const DEFAULT_ORIENTATION_MODEL = 'models/orientation.onnx';
/** The orientation model for one controller or none (recurrent; docs/orientation-model.md). */
export const DEFAULT_ORIENTATION_MODEL_FEWER_DEVICES = 'models/orientation_gru.onnx';

/**
 * URL of a shipped orientation model: `fewerDevices` false, the main model; true, the recurrent
 * one for one controller or none. In the package, where the app's bundler put it.
 */
export function orientationModelUrl(fewerDevices = false): URL {
  return fewerDevices
    ? shippedAssetUrl(DEFAULT_ORIENTATION_MODEL_FEWER_DEVICES, PACKAGE ? () => new URL(/* @vite-ignore */ '../models/orientation_gru.onnx', import.meta.url) : null)
    : shippedAssetUrl(DEFAULT_ORIENTATION_MODEL, PACKAGE ? () => new URL(/* @vite-ignore */ '../models/orientation.onnx', import.meta.url) : null);
}

/**
 * URL of the VR page's database (beside the site's other assets: `assetUrl`); `firstPart`: its
 * first part (`vr.first.mmdb`, a few clips the page starts on; the character moves to the whole
 * after its first frame, `Character.whole()`).
 */
export function vrDatabaseUrl(firstPart = false): URL {
  return assetUrl(firstPart ? DEFAULT_VR_DATABASE.replace(/\.mmdb$/, '.first.mmdb') : DEFAULT_VR_DATABASE);
}
