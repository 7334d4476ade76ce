// Opens `quatcurve view`'s page in Debian's headless Chromium (WebGL2, and with --webgpu
// WebGPU, on SwiftShader) and writes what the test asks of it as JSON: the path drawn and its
// renderer, page errors, any request that left the viewer's origin (none may), and on request
// a captured frame, timed frames or a screenshot. Usage: node view.mjs URL OUT.json [--capture]
// [--measure FRAMES] [--watch SECONDS] [--screenshot FILE.png] [--viewport WxH] [--webgpu].
// QUATCURVE_CHROMIUM names another browser binary.
import { launch, watchedPage } from './chromium.mjs';
import { writeFileSync } from 'node:fs';

const [url, out, ...rest] = process.argv.slice(2);
const option = (name) => {
  const i = rest.indexOf(name);
  return i < 0 ? undefined : rest[i + 1] ?? true;
};
const [width, height] = (option('--viewport') || '1280x720').split('x').map(Number);
const origin = new URL(url).origin;

const browser = await launch({ webgpu: Boolean(option('--webgpu')) });
const result = { errors: [], foreign: [] };
try {
  const page = await watchedPage(browser, { width, height }, origin, result);
  await page.goto(url);
  await page.evaluate(() => window.quatcurveViewer.ready);
  result.renderer = await page.evaluate(() => window.quatcurveViewer.renderer());
  result.path = await page.evaluate(() => window.quatcurveViewer.path());
  if (option('--capture')) result.capture = await page.evaluate(() => window.quatcurveViewer.capture());
  if (option('--watch')) {
    await page.waitForTimeout(1000 * Number(option('--watch')));
    result.frame_times = await page.evaluate(() => window.quatcurveViewer.frameTimes());
  }
  if (option('--measure')) {
    result.measure = await page.evaluate((n) => window.quatcurveViewer.measure(n), Number(option('--measure')));
  }
  if (option('--screenshot')) await page.screenshot({ path: option('--screenshot') });
  result.stats = await page.evaluate(() => document.getElementById('stats').textContent);
  result.message = await page.evaluate(() => document.getElementById('message').textContent);
} catch (e) {
  result.errors.push(String(e));
} finally {
  await browser.close();
}
writeFileSync(out, JSON.stringify(result));
