/**
 * Whether a glTF/GLB file is a VRM model, read from its JSON before the file is parsed: the
 * avatar loader fetches `@pixiv/three-vrm` (~145 kB of script, 20 % of a page's JS) only for a
 * VRM, so a page showing a plain glTF avatar (the shipped one) never downloads or compiles it.
 * A VRM names its extension (VRM 0.x `VRM`, VRM 1.0 `VRMC_vrm`) in the JSON's `extensions`,
 * and — as glTF requires of every extension used — in `extensionsUsed`; either is taken.
 */
export function declaresVrm(bytes: Uint8Array): boolean {
  let json: { extensionsUsed?: unknown; extensions?: unknown };
  try {
    json = JSON.parse(new TextDecoder().decode(jsonChunk(bytes)));
  } catch {
    return false; // not glTF: the loader says what is wrong with it
  }
  const used = Array.isArray(json?.extensionsUsed) ? json.extensionsUsed : [];
  const present = json?.extensions && typeof json.extensions === 'object' ? Object.keys(json.extensions) : [];
  return [...used, ...present].some((name) => name === 'VRM' || name === 'VRMC_vrm');
}

/** The JSON of a glTF file: a GLB's first chunk, or the whole of a `.gltf`. */
function jsonChunk(bytes: Uint8Array): Uint8Array {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  // GLB: a 12-byte header (magic "glTF", version, length), then chunk 0 (length, type "JSON", data).
  if (bytes.byteLength >= 20 && view.getUint32(0, true) === 0x46546c67 && view.getUint32(16, true) === 0x4e4f534a) {
    return bytes.subarray(20, Math.min(bytes.byteLength, 20 + view.getUint32(12, true)));
  }
  return bytes;
}
