// The benchmark's databases, pinned: each is built from a recipe in databases/bench/ (a build
// config naming its takes one by one, with a description of where the list came from), never
// from "every file in a folder", so a number measured today and one measured after ../shared has
// grown are measured on the same work. A recipe is never edited: a new list is a new recipe, and
// the bench prints it as a new row. Built natively into bench-databases/<recipe>.mmdb (not
// shipped, not in dist/), again whenever the recipe or the builder is newer than the file.
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
export const RECIPES = path.join(ROOT, 'databases', 'bench');
export const BUILT = path.join(ROOT, 'bench-databases');

/** The recipe the character-update benchmarks run on (the shipped locomotion config, pinned). */
export const RUNTIME_RECIPE = 'locomotion-2026-11';
/** The recipe whose takes the parse and build benchmark reads. */
export const PARSE_RECIPE = 'cmu16-60fps';

/**
 * Every recipe, by name: `{ name, file, description, clips }` (`clips`: absolute BVH paths).
 * A take a recipe names that is not there is an error naming both: a recipe stays as it was.
 */
export function recipes() {
  return fs
    .readdirSync(RECIPES)
    .filter((f) => f.endsWith('.json'))
    .sort()
    .map((f) => {
      const file = path.join(RECIPES, f);
      const config = JSON.parse(fs.readFileSync(file, 'utf8'));
      const clips = config.clips.map((c) => path.resolve(RECIPES, c.file));
      const missing = clips.filter((c) => !fs.existsSync(c));
      if (missing.length) {
        throw new Error(`databases/bench/${f} names ${missing.length} take(s) that are not there (first: ${path.relative(ROOT, missing[0])}); a recipe is never edited: keep ../shared beside the repo, or add a new recipe`);
      }
      return { name: f.replace(/\.json$/, ''), file, description: config.description ?? '', clips };
    });
}

/** Builds `recipe` into bench-databases/ when missing or older than the recipe or the builder; its path. */
export function recipeDatabase(recipe, mmdb, log) {
  const out = path.join(BUILT, `${recipe.name}.mmdb`);
  const mtime = (p) => (fs.existsSync(p) ? fs.statSync(p).mtimeMs : 0);
  if (mtime(out) > Math.max(mtime(recipe.file), mtime(mmdb))) return out;
  fs.mkdirSync(BUILT, { recursive: true });
  const t = performance.now();
  // Its warnings (repaired rotation spikes…) are the builder's business; shown only on failure.
  execFileSync(mmdb, ['build', '--config', recipe.file, '-o', out], { stdio: ['ignore', 'ignore', 'pipe'] });
  log(`built ${path.relative(ROOT, out)} from databases/bench/${recipe.name}.json in ${((performance.now() - t) / 1000).toFixed(1)} s`);
  return out;
}
