// What the browser drivers share: Debian's headless Chromium launched as a server has it, and
// a page watched for errors and for requests that leave its origin (none may).
import { chromium } from 'playwright-core';

/** Chromium (QUATCURVE_CHROMIUM names another binary). */
export function launch() {
  return chromium.launch({
    executablePath: process.env.QUATCURVE_CHROMIUM || '/usr/bin/chromium',
    // Root in a container has no sandbox; SwiftShader is the GPU a headless server has.
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
  });
}

/**
 * A new page of `browser` at `width` x `height` whose errors (uncaught, console errors) go to
 * `result.errors` and whose requests outside `origin` are refused and listed in
 * `result.foreign`.
 */
export async function watchedPage(browser, { width, height }, origin, result) {
  const page = await browser.newPage({ viewport: { width, height } });
  page.on('pageerror', (e) => result.errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') result.errors.push(m.text()); });
  await page.route('**/*', (route) => {
    if (route.request().url().startsWith(origin)) return route.continue();
    result.foreign.push(route.request().url());
    return route.abort();
  });
  return page;
}
