#!/usr/bin/env node
// Compresses a shipped avatar for the web (run by scripts/setup.mjs' avatars step):
//   node scripts/compress-avatar.mjs <in.glb> <out.glb> [--texture-size 1024] [--json]
//
// With @gltf-transform (a maintained glTF toolkit): duplicate data merged, unused data pruned,
// geometry quantized and meshopt-compressed (EXT_meshopt_compression + KHR_mesh_quantization:
// the library decodes it with three.js' MeshoptDecoder, on the main thread, no worker, CSP-safe
// under 'wasm-unsafe-eval'), textures resized to at most --texture-size px and re-encoded as
// WebP (EXT_texture_webp, decoded by the browser as an image from a blob: URL). The skeleton's
// joints, names and rest pose are untouched: retargeting reads those, not the vertex data.
// Prints one line (or a JSON object with --json) with the sizes before and after.
import fs from 'node:fs';
import path from 'node:path';
import { Logger, NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { dedup, meshopt, prune, textureCompress } from '@gltf-transform/functions';
import { MeshoptEncoder } from 'meshoptimizer';
import sharp from 'sharp';

const args = process.argv.slice(2);
const [input, output] = args.filter((a, i) => !a.startsWith('--') && !args[i - 1]?.startsWith('--texture'));
if (!input || !output) {
  console.error('usage: node scripts/compress-avatar.mjs <in.glb> <out.glb> [--texture-size 1024] [--json]');
  process.exit(2);
}
const sizeArg = args.indexOf('--texture-size');
const textureSize = sizeArg >= 0 ? Number(args[sizeArg + 1]) : 1024;

await MeshoptEncoder.ready;
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS).registerDependencies({ 'meshopt.encoder': MeshoptEncoder });
const t0 = performance.now();
const document = await io.read(input);
document.setLogger(new Logger(Logger.Verbosity.WARN)); // not each pruned accessor
await document.transform(
  dedup(),
  // Keep vertex attributes a material could read (COLOR_0 tints in three.js): only unused nodes,
  // accessors, textures… go.
  prune({ keepAttributes: true, keepLeaves: true }),
  textureCompress({ encoder: sharp, targetFormat: 'webp', resize: [textureSize, textureSize], quality: 85 }),
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
const result = { input, output, before, after: bytes.length, textureSize, ms: Math.round(performance.now() - t0) };
if (args.includes('--json')) console.log(JSON.stringify(result));
else console.log(`${path.basename(output)}: ${(before / 1e6).toFixed(2)} MB → ${(bytes.length / 1e6).toFixed(2)} MB (meshopt geometry, WebP ≤ ${textureSize} px textures) in ${(result.ms / 1000).toFixed(1)} s`);
