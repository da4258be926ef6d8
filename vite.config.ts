import { fileURLToPath } from 'node:url';
import { defineConfig } from 'vitest/config';

const root = fileURLToPath(new URL('.', import.meta.url));

export default defineConfig({
  root,
  publicDir: 'public',
  server: {
    port: 5173,
    fs: { allow: [root] },
  },
  build: {
    outDir: 'dist',
    target: 'es2022',
  },
  // onnxruntime-web ships its own wasm loader that pre-bundling breaks.
  optimizeDeps: { exclude: ['onnxruntime-web'] },
  test: {
    include: ['tests/unit/**/*.test.ts', 'web/**/*.test.ts'],
    environment: 'node',
    testTimeout: 30_000,
  },
});
