// Replays the hostile-input corpus through the WASM build in Node and compares each outcome
// with the native one recorded in cases.json (docs/robustness.md, "Replaying the cases").
//
//   cargo run --release --bin mmdb-cases -- /tmp/cases
//   cargo build --release --target wasm32-unknown-unknown --lib
//   wasm-bindgen --target nodejs --out-dir /tmp/wasmpkg --out-name mmcore \
//       target/wasm32-unknown-unknown/release/mmcore.wasm
//   node fuzz/replay_wasm.mjs /tmp/cases /tmp/wasmpkg/mmcore.js
//
// BVH cases go through bvh_info (the parser), .mmdb cases through RawDatabase (the loader)
// and, when they load, inspect_json and a RawCrowd playing 30 updates. Exits 1 on any
// disagreement, trap or message mismatch.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const [dir, pkg] = process.argv.slice(2);
if (!dir || !pkg) {
  console.error('usage: node replay_wasm.mjs CASES_DIR PATH/TO/mmcore.js');
  process.exit(2);
}
const wasm = createRequire(import.meta.url)(path.resolve(pkg));
const cases = JSON.parse(fs.readFileSync(path.join(dir, 'cases.json'), 'utf8'));
const failures = [];
let ok = 0;
for (const c of cases) {
  const bytes = fs.readFileSync(path.join(dir, c.file));
  let outcome = 'ok';
  let message = null;
  try {
    if (c.kind === 'bvh') {
      wasm.bvh_info('case.bvh', bytes);
    } else {
      const db = new wasm.RawDatabase(bytes);
      JSON.parse(db.inspect_json());
      db.free();
      const crowd = new wasm.RawCrowd(bytes, 1);
      for (let i = 0; i < 30; i++) {
        crowd.set_input(0, Math.sin(i), 1, 0, 1, false, false);
        crowd.update(1 / 60);
      }
      crowd.free();
    }
  } catch (e) {
    outcome = 'error';
    message = String(e.message ?? e);
    if (e instanceof WebAssembly.RuntimeError) message = `trap: ${message}`;
  }
  if (outcome !== c.native) failures.push(`${c.file}: wasm ${outcome} (${message}), native ${c.native} (${c.message})`);
  else if (outcome === 'error' && c.message && !c.message.endsWith(message) && !message.endsWith(c.message)) {
    failures.push(`${c.file}: wasm says ${JSON.stringify(message)}, native ${JSON.stringify(c.message)}`);
  } else ok++;
}
console.log(`${ok} passed, ${failures.length} failed`);
for (const f of failures.slice(0, 40)) console.log(f);
process.exit(failures.length ? 1 : 0);
