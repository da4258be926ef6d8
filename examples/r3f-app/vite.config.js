import { defineConfig } from 'vite';

export default defineConfig({
  // JSX with React's automatic runtime (no plugin needed for a build).
  esbuild: { jsx: 'automatic' },
  // `npm run dev` only: serve mm-avatar as it is, so its asset URLs point into the package
  // (see the vite example).
  optimizeDeps: { exclude: ['mm-avatar'] },
});
