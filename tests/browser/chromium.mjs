// What the browser drivers share: Debian's headless Chromium launched as a server has it, and
// a page watched for errors and for requests that leave its origin (none may).
import { chromium } from 'playwright-core';

// WebGPU, which Chromium offers on Linux only when asked, on SwiftShader; its compositor on
// SwiftShader's Vulkan without a window surface, since without those three flags presenting a
// WebGPU canvas loses the GPU process (every later call rejects with "A valid external
// Instance reference no longer exists"). Only pages that draw with WebGPU get them: under
// them WebGL2 pages now and then lose their context.
const WEBGPU_ARGS = ['--enable-unsafe-webgpu', '--use-webgpu-adapter=swiftshader', '--enable-features=Vulkan',
  '--use-vulkan=swiftshader', '--disable-vulkan-surface'];

/** Chromium (QUATCURVE_CHROMIUM names another binary), with WebGPU when `webgpu`. */
export function launch({ webgpu = false } = {}) {
  return chromium.launch({
    executablePath: process.env.QUATCURVE_CHROMIUM || '/usr/bin/chromium',
    // Root in a container has no sandbox; SwiftShader is the GPU a headless server has. A
    // frame of a thousand characters on a shared CPU may outlast the GPU watchdog.
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
      '--disable-gpu-watchdog', ...(webgpu ? WEBGPU_ARGS : [])],
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
