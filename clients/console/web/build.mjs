// Bundles the web app into one directory the console serves as it is:
//   node build.mjs --outdir=DIR   ->  DIR/index.html, DIR/app.js, DIR/app.css
// Everything is local (uPlot's CSS included); nothing is fetched from
// elsewhere at run time. The page names its assets with a content hash in
// the query string, so a browser never mixes an old app.js with a new page.

import { createHash } from 'node:crypto';
import { mkdir, readFile, rm, stat, writeFile } from 'node:fs/promises';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import * as esbuild from 'esbuild';

const here = path.dirname(fileURLToPath(import.meta.url));
const BUDGET_BYTES = 500 * 1024; // first load; the aim is far below

function parseArgs(argv) {
  const args = { outdir: path.join(here, 'dist') };
  for (const arg of argv) {
    const [key, value] = arg.split('=');
    if (key === '--outdir' && value) args.outdir = path.resolve(value);
    else throw new Error(`unknown argument ${arg} (usage: node build.mjs --outdir=DIR)`);
  }
  return args;
}

const digest = (text) => createHash('sha256').update(text).digest('hex').slice(0, 12);

async function main() {
  const { outdir } = parseArgs(process.argv.slice(2));
  await mkdir(outdir, { recursive: true });
  // A stale sourcemap or chunk from an older build must not be served.
  await Promise.all(['app.js', 'app.css', 'index.html'].map((f) => rm(path.join(outdir, f), { force: true })));

  await esbuild.build({
    entryPoints: { app: path.join(here, 'src/main.js') },
    bundle: true,
    minify: true,
    format: 'esm',
    target: ['es2020', 'chrome100', 'firefox100', 'safari15'],
    outdir,
    legalComments: 'none',
    logLevel: 'warning',
  });

  const js = await readFile(path.join(outdir, 'app.js'), 'utf8');
  const css = await readFile(path.join(outdir, 'app.css'), 'utf8');
  const template = await readFile(path.join(here, 'src/index.html'), 'utf8');
  const html = template
    .replace(/<!--[\s\S]*?-->/g, '')
    .replace('href="app.css"', `href="app.css?v=${digest(css)}"`)
    .replace('src="app.js"', `src="app.js?v=${digest(js)}"`)
    .replace(/\n\s*/g, '\n');
  if (!html.includes('app.js?v=') || !html.includes('app.css?v=')) {
    throw new Error('src/index.html must load app.js and app.css');
  }
  await writeFile(path.join(outdir, 'index.html'), html);

  let total = 0;
  for (const file of ['index.html', 'app.js', 'app.css']) {
    const { size } = await stat(path.join(outdir, file));
    total += size;
    console.log(`${file.padEnd(10)} ${String(size).padStart(7)} bytes`);
  }
  console.log(`total      ${String(total).padStart(7)} bytes`);
  if (total > BUDGET_BYTES) throw new Error(`first load ${total} bytes exceeds the ${BUDGET_BYTES}-byte budget`);
}

main().catch((err) => {
  console.error(err.message);
  process.exit(1);
});
