import { defineConfig } from "vite";

// `npm run dev` proxies the API to a `crossroads serve` on :8000; `npm run build` writes dist/.
export default defineConfig({
  build: { outDir: "dist", emptyOutDir: true },
  server: { proxy: { "/api": "http://127.0.0.1:8000" } },
});
