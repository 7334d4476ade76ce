// Opens an engine's test page (tests/browser/ENGINE/: three for the quatcurve-three package,
// three-fbx for three.js's FBX reader beside a bake, babylon for Babylon.js playing Babylon
// bakes) in Debian's headless Chromium (WebGL2 on SwiftShader), serving it, what the pages
// share (common/), the package (packages/quatcurve-three/), the engines
// (node_modules/three/, node_modules/babylonjs*/) and a directory of bakes and sources
// (/data/) from one local origin, as a user's static server would. Writes the page's result
// as JSON: its errors, any request that left the origin (none may), and what the page
// measured (its `window.quatcurveTest`). With --example, opens examples/ENGINE/ as shipped
// instead, its engine's scripts from unpkg answered from node_modules (the versions it names
// must be the ones installed), and reports its title once it sets `window.exampleReady` (or
// after a few seconds). With --package DIR, the package is served from DIR (a copy a user
// installed) instead of the repository's.
// Usage: node engines.mjs ENGINE DATA_DIR QUERY OUT.json [--example] [--package DIR] [--screenshot FILE.png] [--viewport WxH]
import { launch, watchedPage } from './chromium.mjs';
import { createServer } from 'node:http';
import { readFile, writeFile } from 'node:fs/promises';
import { extname, join, normalize, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const [engine, dataDir, query, out, ...rest] = process.argv.slice(2);
const option = (name) => {
  const i = rest.indexOf(name);
  return i < 0 ? undefined : rest[i + 1] ?? true;
};
const here = fileURLToPath(new URL('.', import.meta.url));
const repository = resolve(here, '../..');
const roots = {
  '/page/': join(here, engine),
  '/common/': join(here, 'common'),
  '/pkg/': resolve(option('--package') || join(repository, 'packages/quatcurve-three')),
  '/packages/': join(repository, 'packages'),
  '/examples/': join(repository, 'examples'),
  '/three/': join(here, 'node_modules/three'),
  '/babylonjs/': join(here, 'node_modules/babylonjs'),
  '/babylonjs-loaders/': join(here, 'node_modules/babylonjs-loaders'),
  '/data/': resolve(dataDir),
};
const types = { '.html': 'text/html', '.js': 'text/javascript', '.json': 'application/json', '.glsl': 'text/plain' };

const server = createServer(async (request, response) => {
  const path = decodeURIComponent(new URL(request.url, 'http://x').pathname);
  const prefix = Object.keys(roots).find((p) => path.startsWith(p));
  const file = prefix && normalize(join(roots[prefix], path.slice(prefix.length)));
  if (!file || !file.startsWith(roots[prefix])) {
    response.writeHead(404).end();
    return;
  }
  try {
    const body = await readFile(file);
    response.writeHead(200, { 'content-type': types[extname(file)] || 'application/octet-stream' }).end(body);
  } catch {
    response.writeHead(404).end();
  }
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const origin = `http://127.0.0.1:${server.address().port}`;

const [width, height] = (option('--viewport') || '512x512').split('x').map(Number);
const browser = await launch();
const result = { errors: [], foreign: [] };
try {
  const page = await watchedPage(browser, { width, height }, origin, result);
  page.on('requestfailed', (r) => result.errors.push(`${r.url()}: ${r.failure()?.errorText}`));
  page.on('response', (r) => { if (r.status() >= 400) result.errors.push(`${r.url()}: ${r.status()}`); });
  if (option('--example')) {
    // unpkg.com/PACKAGE@VERSION/PATH, answered from node_modules/PACKAGE when VERSION is the
    // installed one (any other is refused, and the page errs).
    await page.route('https://unpkg.com/**', async (route) => {
      const [, name, version, path] = route.request().url().match(/^https:\/\/unpkg\.com\/([^@]+)@([^/]+)\/(.*)$/) ?? [];
      const dir = join(here, 'node_modules', name ?? '');
      const installed = name && JSON.parse(await readFile(join(dir, 'package.json')).catch(() => '{}')).version;
      if (!name || installed !== version) {
        result.errors.push(`${route.request().url()}: not the installed ${name}@${installed}`);
        return route.abort();
      }
      route.fulfill({ body: await readFile(join(dir, path)), contentType: 'text/javascript' });
    });
    await page.goto(`${origin}/examples/${engine}/index.html?${query}`);
    await page.waitForFunction(() => window.exampleReady, null, { timeout: 60000 }).catch(() => {});
    result.title = await page.title();
  } else {
    await page.goto(`${origin}/page/index.html?${query}`);
    result.page = await page.evaluate(() => window.quatcurveTest);
  }
  if (option('--screenshot')) await page.screenshot({ path: option('--screenshot') });
} catch (e) {
  result.errors.push(String(e));
} finally {
  await browser.close();
  server.close();
}
await writeFile(out, JSON.stringify(result));
