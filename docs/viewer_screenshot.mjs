// Screenshot of the rerun web viewer in headless Chromium, for docs/viewer.png.
//
//   node --experimental-websocket docs/viewer_screenshot.mjs URL OUT.png WAIT_MS [CLICK_X,CLICK_Y]
//
// URL is the web viewer page of `rerun --serve-web FILE.rrd` (see docs/viewer.md). The page is
// given WAIT_MS to load the viewer and the recording; an optional click (CSS pixels; e.g. on the
// time bar, to put the time cursor inside a flip) follows, then the screenshot. Chromium renders
// WebGL with SwiftShader (CPU), so no GPU or display is needed. Uses the Chrome DevTools
// Protocol over Node's built-in WebSocket (Node >= 20 with --experimental-websocket).
import { spawn } from 'node:child_process';
import { writeFileSync } from 'node:fs';

const [url, out, waitMs, click] = process.argv.slice(2);
const [W, H] = [1920, 1080];
const PORT = 9333;
const chrome = spawn('chromium', ['--headless=new', '--no-sandbox', '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist', `--window-size=${W},${H}`,
  `--remote-debugging-port=${PORT}`, 'about:blank'], { stdio: 'ignore' });
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
try {
  let targets;
  for (let i = 0; i < 100 && !targets; i++) {
    try { targets = await (await fetch(`http://127.0.0.1:${PORT}/json`)).json(); } catch { await sleep(200); }
  }
  const ws = new WebSocket(targets.find((t) => t.type === 'page').webSocketDebuggerUrl);
  await new Promise((r) => { ws.onopen = r; });
  let id = 0;
  const pending = new Map();
  ws.onmessage = (m) => {
    const d = JSON.parse(m.data);
    if (d.id && pending.has(d.id)) { pending.get(d.id)(d); pending.delete(d.id); }
  };
  const send = (method, params = {}) => new Promise((r) => {
    pending.set(++id, r);
    ws.send(JSON.stringify({ id, method, params }));
  });
  await send('Emulation.setDeviceMetricsOverride', { width: W, height: H, deviceScaleFactor: 1, mobile: false });
  await send('Page.navigate', { url });
  await sleep(+waitMs);
  if (click) {
    const [x, y] = click.split(',').map(Number);
    for (const type of ['mouseMoved', 'mousePressed', 'mouseReleased']) {
      await send('Input.dispatchMouseEvent', { type, x, y, button: 'left', clickCount: 1 });
    }
    await sleep(3000);
  }
  await send('Input.dispatchMouseEvent', { type: 'mouseMoved', x: W - 5, y: 5 }); // no hover tooltip
  await sleep(3000);
  const shot = await send('Page.captureScreenshot', { format: 'png' });
  writeFileSync(out, Buffer.from(shot.result.data, 'base64'));
  console.error(`wrote ${out}`);
} finally {
  chrome.kill();
}
process.exit(0);
