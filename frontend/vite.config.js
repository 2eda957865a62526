import { copyFileSync, mkdirSync } from "node:fs";
import { createRequire } from "node:module";
import { dirname, join } from "node:path";
import { defineConfig } from "vite";

const require = createRequire(import.meta.url);

// The API docs' pages (/docs: Swagger UI, /redoc: ReDoc) load these from the studio's own build,
// so they work offline; the API points FastAPI's doc pages at /vendor/... (api/main.py).
const VENDOR = {
  "swagger-ui": ["swagger-ui-dist/package.json", ["swagger-ui-bundle.js", "swagger-ui.css", "favicon-32x32.png"]],
  redoc: ["redoc/package.json", ["bundles/redoc.standalone.js"]],
};

function vendorDocs() {
  return {
    name: "crossroads-vendor-docs",
    writeBundle(options) {
      for (const [name, [pkg, files]] of Object.entries(VENDOR)) {
        const root = dirname(require.resolve(pkg));
        const out = join(options.dir, "vendor", name);
        mkdirSync(out, { recursive: true });
        for (const file of files) copyFileSync(join(root, file), join(out, file.split("/").pop()));
      }
    },
  };
}

// `npm run dev` proxies the API to a `crossroads serve` on :8000; `npm run build` writes dist/.
export default defineConfig({
  build: { outDir: "dist", emptyOutDir: true },
  plugins: [vendorDocs()],
  server: { proxy: { "/api": "http://127.0.0.1:8000" } },
});
