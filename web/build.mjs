// Bundles the page into dist/: main.js (the sources and three.js, one ES module),
// index.html and style.css. `node build.mjs --watch` rebuilds on every change.
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
const options = {
  entryPoints: [join(here, 'src', 'main.js')],
  outfile: join(dist, 'main.js'),
  bundle: true,
  format: 'esm',
  target: 'es2022',
  minify: true,
  sourcemap: true,
  legalComments: 'linked',
  logLevel: 'warning',
  plugins: [copy_static],
};

if (watch) {
  const context = await esbuild.context(options);
  await context.watch();
  console.log('watching web/src: rebuilding dist/ on every change');
} else {
  await esbuild.build(options);
}
