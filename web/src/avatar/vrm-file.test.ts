import { describe, expect, it } from 'vitest';
import { declaresVrm } from './vrm-file.ts';

/** A GLB with `json` as its JSON chunk (padded with spaces to 4 bytes) and an empty BIN chunk. */
function glb(json: object): Uint8Array {
  let text = JSON.stringify(json);
  while (text.length % 4) text += ' ';
  const body = new TextEncoder().encode(text);
  const out = new Uint8Array(20 + body.length + 8);
  const view = new DataView(out.buffer);
  view.setUint32(0, 0x46546c67, true); // "glTF"
  view.setUint32(4, 2, true);
  view.setUint32(8, out.length, true);
  view.setUint32(12, body.length, true);
  view.setUint32(16, 0x4e4f534a, true); // "JSON"
  out.set(body, 20);
  view.setUint32(20 + body.length, 0, true);
  view.setUint32(24 + body.length, 0x004e4942, true); // "BIN\0"
  return out;
}

describe('declaresVrm', () => {
  it('finds VRM 1.0 and VRM 0.x in a GLB', () => {
    expect(declaresVrm(glb({ asset: { version: '2.0' }, extensionsUsed: ['VRMC_vrm', 'KHR_materials_unlit'] }))).toBe(true);
    expect(declaresVrm(glb({ asset: { version: '2.0' }, extensions: { VRM: { specVersion: '0.0' } } }))).toBe(true);
  });
  it('says no for a plain glTF, in a GLB or as JSON text', () => {
    expect(declaresVrm(glb({ asset: { version: '2.0' }, extensionsUsed: ['EXT_meshopt_compression'] }))).toBe(false);
    expect(declaresVrm(new TextEncoder().encode('{"asset":{"version":"2.0"}}'))).toBe(false);
    expect(declaresVrm(new TextEncoder().encode('{"asset":{"version":"2.0"},"extensionsUsed":["VRMC_vrm"]}'))).toBe(true);
  });
  it('says no (and does not throw) for bytes that are not glTF', () => {
    expect(declaresVrm(new Uint8Array([1, 2, 3]))).toBe(false);
    expect(declaresVrm(new TextEncoder().encode('null'))).toBe(false);
    const truncated = glb({ extensionsUsed: ['VRMC_vrm'] }).subarray(0, 30);
    expect(declaresVrm(truncated)).toBe(false);
  });
});
