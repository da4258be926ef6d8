/**
 * The VR entry's shipped assets: the orientation models (only this entry names them, so a desktop
 * app's bundler never copies them; assets.ts explains the literal URLs) and the VR page's
 * database (not in the package: the site serves it, `setAssetBase` finds it elsewhere).
 */
import { PACKAGE, assetUrl, shippedAssetUrl } from '../assets.ts';

/** The VR page's database (docs/database.md, `vr.json`): slow walks, steps, gestures, idle. */
export const DEFAULT_VR_DATABASE = 'databases/vr.mmdb';
/** The feed-back orientation network (docs/orientation-model.md). */
export const DEFAULT_ORIENTATION_MODEL = 'models/orientation.onnx';
/** The recurrent orientation model, averaged with the network's yaw (docs/orientation-model.md). */
export const DEFAULT_ORIENTATION_MODEL_RECURRENT = 'models/orientation_gru.onnx';

/**
 * URL of a shipped orientation model: `recurrentModel` false, the feed-back network; true, the
 * recurrent model. In the package, where the app's bundler put it.
 */
export function orientationModelUrl(recurrentModel = false): URL {
  return recurrentModel
    ? shippedAssetUrl(DEFAULT_ORIENTATION_MODEL_RECURRENT, PACKAGE ? () => new URL(/* @vite-ignore */ '../models/orientation_gru.onnx', import.meta.url) : null)
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
