/**
 * A GLB's own images decoded straight from its bytes. three.js' GLTFLoader turns each image stored
 * in the file into a `blob:` URL and fetches it back before decoding it: a request through the
 * browser's blob registry per image, on the way to the first frame — and DevTools' network
 * emulation delays those fetches like any other (80 ms each in the load bench's throttled runs,
 * where the shipped avatar's five textures waited for it). Here they go to `createImageBitmap`
 * with the bytes, decoding on the browser's image threads from the start.
 *
 * How: GLTFLoader passes a bufferView image's bytes to its texture loader's `parse` when that
 * loader says it is a KTX2 loader (three.js r187, this package's); this loader says so, decodes
 * any image format the browser does (the bytes name their format), and loads images by URL
 * through three.js' `ImageBitmapLoader` as before. A three.js without that path uses its blob URLs
 * with the same `ImageBitmapLoader`: the same textures, only not sooner (and a page's CSP must
 * then allow `connect-src blob:`; the embed e2e's does not). Where the browser has no
 * `createImageBitmap` (older Safari, Node) GLTFLoader's own `TextureLoader` stays.
 */
import * as THREE from 'three';
import type { GLTFLoaderPlugin, GLTFParser } from 'three/addons/loaders/GLTFLoader.js';

/** `createImageBitmap`'s options as `ImageBitmapLoader` sets them for GLTFLoader. */
const BITMAP: ImageBitmapOptions = { premultiplyAlpha: 'none', colorSpaceConversion: 'none' };

/** Registered with `GLTFLoader.register`: makes `parser` decode the file's images from its bytes. */
export function embeddedImages(parser: GLTFParser): GLTFLoaderPlugin {
  const byUrl = parser.textureLoader;
  if ((byUrl as THREE.ImageBitmapLoader).isImageBitmapLoader) {
    const loader = {
      isImageBitmapLoader: true,
      isKTX2Loader: true,
      load: byUrl.load.bind(byUrl),
      parse(bytes: ArrayBuffer, onLoad: (texture: THREE.Texture) => void, onError: (error: unknown) => void): void {
        createImageBitmap(new Blob([bytes]), BITMAP).then((bitmap) => {
          const texture = new THREE.Texture(bitmap);
          texture.needsUpdate = true;
          onLoad(texture);
        }, onError);
      },
    };
    parser.textureLoader = loader as unknown as THREE.ImageBitmapLoader;
  }
  return { name: 'MM_embedded_images' };
}
