import { fileURLToPath } from 'node:url';
import basicSsl from '@vitejs/plugin-basic-ssl';
import { defineConfig } from 'vitest/config';

const root = fileURLToPath(new URL('.', import.meta.url));

export default defineConfig({
  root,
  publicDir: 'public',
  // `npm start -- --https` (scripts/setup.mjs sets VITE_HTTPS=1): a self-signed certificate made
  // locally, because Quest Browser allows WebXR only on secure origins.
  plugins: process.env.VITE_HTTPS === '1' ? [basicSsl({ name: 'mm-avatar-dev' })] : [],
  server: {
    port: 5173,
    fs: { allow: [root] },
  },
  build: {
    outDir: 'dist',
    target: 'es2022',
  },
  // onnxruntime-web ships its own wasm loader that pre-bundling breaks.
  // iwer and its devui are imported lazily (vr.html?emulate=1); pre-bundling them up front keeps
  // vite from re-optimizing mid-session and reloading the page.
  optimizeDeps: { exclude: ['onnxruntime-web'], include: ['iwer', '@iwer/devui'] },
  test: {
    include: ['tests/unit/**/*.test.ts', 'web/**/*.test.ts', 'server/**/*.test.ts'],
    environment: 'node',
    testTimeout: 30_000,
  },
});
