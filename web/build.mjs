// Bundles the page into dist/: main.js (the sources and three.js, one ES module),
// parse_worker.js (a classic worker script, which every browser can start), index.html and
// style.css. `node build.mjs --watch` rebuilds on every change.
import * as esbuild from 'esbuild';
import { copyFile, mkdir } from 'node:fs/promises';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const dist = join(here, 'dist');
const watch = process.argv.includes('--watch');

const copy_static = {
  name: 'copy-static',
  setup(build) {
    build.onEnd(async (result) => {
      if (result.errors.length) return;
      await copyFile(join(here, 'index.html'), join(dist, 'index.html'));
      await copyFile(join(here, 'src', 'style.css'), join(dist, 'style.css'));
    });
  },
};

await mkdir(dist, { recursive: true });
const common = {
  bundle: true,
  target: 'es2022',
  minify: true,
  sourcemap: true,
  legalComments: 'linked',
  logLevel: 'warning',
};
const builds = [
  { ...common, entryPoints: [join(here, 'src', 'main.js')], outfile: join(dist, 'main.js'), format: 'esm', plugins: [copy_static] },
  { ...common, entryPoints: [join(here, 'src', 'parse_worker.js')], outfile: join(dist, 'parse_worker.js'), format: 'iife' },
];

if (watch) {
  for (const options of builds) await (await esbuild.context(options)).watch();
  console.log('watching web/src: rebuilding dist/ on every change');
} else {
  await Promise.all(builds.map((options) => esbuild.build(options)));
}
