/**
 * `roomsPlugin()`: the room server on vite's own http(s) server, so `npm start` serves the rooms
 * on the page's origin (ws:// on http, wss:// with `--https`). Also on `vite preview`.
 *
 * ```ts
 * // vite.config.ts
 * import { roomsPlugin } from './server/vite-plugin.ts';
 * export default defineConfig({ plugins: [roomsPlugin()] });
 * ```
 */
import type { Plugin } from 'vite';
import { attachRooms, roomsRequestHandler, type RoomsHandle, type RoomsOptions } from './rooms.ts';

export function roomsPlugin(options: RoomsOptions = {}): Plugin {
  let handle: RoomsHandle | null = null;
  const attach = (server: { httpServer: Parameters<typeof attachRooms>[0] | null; middlewares: { use: (fn: ReturnType<typeof roomsRequestHandler>) => unknown } }) => {
    if (!server.httpServer) return; // middleware mode: the host server attaches rooms itself
    // ROOMS_NATS_URL: this dev server shares its rooms with other room servers (docs/rooms.md).
    handle = attachRooms(server.httpServer, { nats: process.env.ROOMS_NATS_URL, ...options });
    server.middlewares.use(roomsRequestHandler(options));
    server.httpServer.once('close', () => void handle?.close());
  };
  return {
    name: 'mm-rooms',
    configureServer(server) {
      attach(server as Parameters<typeof attach>[0]);
    },
    configurePreviewServer(server) {
      attach(server as Parameters<typeof attach>[0]);
    },
  };
}
