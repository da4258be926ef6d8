import { defineConfig } from 'vite';

export default defineConfig({
  // Only for `npm run dev`: vite's dev server pre-bundles dependencies into node_modules/.vite,
  // where mm-avatar's `new URL('…', import.meta.url)` asset references would point nowhere;
  // served as it is, they point into the package. `vite build` needs nothing.
  optimizeDeps: { exclude: ['mm-avatar'] },
});
