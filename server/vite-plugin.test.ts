/** roomsPlugin() on a real vite dev server: rooms on the page's origin, POST /rooms, HMR untouched. */
import { mkdtempSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { createServer } from 'vite';
import { expect, it } from 'vitest';
import { WebSocket } from 'ws';
import { isRoomId } from '../web/src/rooms/protocol.ts';
import { TestClient, moveBytes } from './test-helpers.ts';
import { roomsPlugin } from './vite-plugin.ts';

it('serves /rooms/<id> and POST /rooms on the vite dev server, leaving vite-hmr alone', async () => {
  const root = mkdtempSync(join(tmpdir(), 'rooms-vite-'));
  writeFileSync(join(root, 'index.html'), '<!doctype html><title>rooms</title>');
  const vite = await createServer({ root, configFile: false, logLevel: 'silent', plugins: [roomsPlugin()], server: { port: 0, host: '127.0.0.1', strictPort: false } });
  try {
    await vite.listen();
    const address = vite.httpServer!.address();
    const port = typeof address === 'object' && address ? address.port : 0;
    const origin = `http://127.0.0.1:${port}`;
    const res = await fetch(`${origin}/rooms`, { method: 'POST' });
    expect(res.status).toBe(201);
    const { id } = (await res.json()) as { id: string };
    expect(isRoomId(id)).toBe(true);
    const page = await fetch(`${origin}/`);
    expect(page.status).toBe(200); // vite still serves the page

    const server = { url: (room: string) => `ws://127.0.0.1:${port}/rooms/${room}`, origin } as Parameters<typeof TestClient.join>[0];
    const a = await TestClient.join(server, id, 'a');
    const b = await TestClient.join(server, id, 'b');
    a.send(moveBytes(1, 5));
    const relay = await b.waitFor((m) => m.type === 'relay');
    expect(relay.type === 'relay' && relay.from).toBe(a.memberId);
    await expect(TestClient.open(`ws://127.0.0.1:${port}/rooms/${id}`, 'https://evil.example')).rejects.toThrow('HTTP 403');

    // vite's own HMR socket still answers on the same server (vite checks its token).
    const token = (vite.config as unknown as { webSocketToken: string }).webSocketToken;
    const hmr = new WebSocket(`ws://127.0.0.1:${port}/?token=${token}`, 'vite-hmr', { origin });
    const hmrOpened = await new Promise<boolean>((resolve) => {
      hmr.once('open', () => resolve(true));
      hmr.once('error', () => resolve(false));
    });
    expect(hmrOpened).toBe(true);
    hmr.close();
    a.ws.terminate();
    b.ws.terminate();
  } finally {
    await vite.close();
    rmSync(root, { recursive: true, force: true });
  }
});
