#!/usr/bin/env node
// Compresses a shipped avatar for the web (run by scripts/setup.mjs' avatars step):
//   node scripts/compress-avatar.mjs <in.glb> <out.glb> [--texture-size 512] [--data-texture-size 256] [--json]
//
// With @gltf-transform (a maintained glTF toolkit): duplicate data merged, unused data pruned
// (vertex attributes no material reads among them, and vertex colours that are all white),
// geometry quantized and meshopt-compressed (EXT_meshopt_compression + KHR_mesh_quantization:
// the library decodes it with three.js' MeshoptDecoder, on the main thread, no worker, CSP-safe
// under 'wasm-unsafe-eval'), textures resized and re-encoded as WebP (EXT_texture_webp, decoded
// by the browser as an image from a blob: URL). The skeleton's joints, names and rest pose are
// untouched: retargeting reads those, not the vertex data.
//
// Texture sizes: colour and normal maps at most --texture-size px (512: a character on a page is
// a few hundred pixels tall, its face a tenth of its colour map), the maps of surface data
// (metallic-roughness, occlusion: slow variations of shininess) at most --data-texture-size
// (256). Why not more: every pixel is decoded and uploaded before the first frame — the shipped
// avatar's three 1024² maps took 37-58 ms each to decode, and a returning visitor's first frame
// came ~50 ms sooner at 512/256 (348 → 245 kB on the wire).
// Prints one line (or a JSON object with --json) with the sizes before and after.
import fs from 'node:fs';
import path from 'node:path';
import { Logger, NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { dedup, meshopt, prune, textureCompress } from '@gltf-transform/functions';
import { MeshoptEncoder } from 'meshoptimizer';
import sharp from 'sharp';

const args = process.argv.slice(2);
const [input, output] = args.filter((a, i) => !a.startsWith('--') && !/^--(data-)?texture-size$/.test(args[i - 1] ?? ''));
if (!input || !output) {
  console.error('usage: node scripts/compress-avatar.mjs <in.glb> <out.glb> [--texture-size 512] [--data-texture-size 256] [--json]');
  process.exit(2);
}
const sizeOf = (flag, fallback) => (args.includes(flag) ? Number(args[args.indexOf(flag) + 1]) : fallback);
const textureSize = sizeOf('--texture-size', 512);
const dataTextureSize = sizeOf('--data-texture-size', 256);
// (A map a material uses both as colour and as data — rare — is taken by the data pass: 256.)
const DATA_SLOTS = /^(metallicRoughness|occlusion)Texture$/;

/**
 * Removes COLOR_0 where every vertex is white. glTF multiplies a material's base colour by it
 * (three.js compiles that into the shaders of any mesh that has it): all ones changes no pixel.
 */
function dropWhiteVertexColors() {
  return (doc) => {
    const element = [];
    for (const mesh of doc.getRoot().listMeshes()) {
      for (const primitive of mesh.listPrimitives()) {
        const color = primitive.getAttribute('COLOR_0');
        if (!color || primitive.listTargets().some((t) => t.getAttribute('COLOR_0'))) continue;
        let white = true;
        for (let i = 0; white && i < color.getCount(); i++) white = color.getElement(i, element).every((v) => v >= 1 - 1e-6);
        if (white) primitive.setAttribute('COLOR_0', null);
      }
    }
  };
}

await MeshoptEncoder.ready;
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS).registerDependencies({ 'meshopt.encoder': MeshoptEncoder });
const t0 = performance.now();
const document = await io.read(input);
document.setLogger(new Logger(Logger.Verbosity.WARN)); // not each pruned accessor
await document.transform(
  dedup(),
  // Vertex attributes no material reads go too (UV sets no texture names, COLOR_1 and up: exports
  // carry them by the handful), then an all-white COLOR_0: every byte of them was downloaded,
  // decoded and uploaded to the GPU before the first frame for nothing.
  prune({ keepAttributes: false, keepLeaves: true }),
  dropWhiteVertexColors(),
  textureCompress({ encoder: sharp, targetFormat: 'webp', resize: [dataTextureSize, dataTextureSize], quality: 85, slots: DATA_SLOTS }),
  textureCompress({ encoder: sharp, targetFormat: 'webp', resize: [textureSize, textureSize], quality: 85, slots: /^(?!(metallicRoughness|occlusion)Texture$)/ }),
  meshopt({ encoder: MeshoptEncoder, level: 'medium' }),
);
const bytes = await io.writeBinary(document);

// Write beside, then rename: a reader never sees half a file, and an interrupted run leaves
// the old output (older than its source, so the next set-up redoes it).
const tmp = `${output}.tmp-${process.pid}`;
fs.mkdirSync(path.dirname(output), { recursive: true });
fs.writeFileSync(tmp, bytes);
fs.renameSync(tmp, output);
const before = fs.statSync(input).size;
const result = { input, output, before, after: bytes.length, textureSize, dataTextureSize, ms: Math.round(performance.now() - t0) };
if (args.includes('--json')) console.log(JSON.stringify(result));
else console.log(`${path.basename(output)}: ${(before / 1e6).toFixed(2)} MB → ${(bytes.length / 1e6).toFixed(2)} MB (meshopt geometry, WebP textures ≤ ${textureSize} px, data maps ≤ ${dataTextureSize} px) in ${(result.ms / 1000).toFixed(1)} s`);
