// SPDX-License-Identifier: Apache-2.0
// fovea-monitor in a real browser (Debian's chromium, headless, driven by puppeteer-core): with the
// synthetic-eye source, the eye image updates and the gaze and labels move; a STATUS value matches
// `fovea-ctl status`; the calibration's validation is drawn; the screenshot shows the eye with a
// pupil drawn over it, the gaze on the screen and the error vectors; a marker sent from the page is
// accepted; a WebSocket from another origin, without the
// token, or a request naming another Host is refused.
//
// Usage: node monitor.test.mjs BUILD_DIR [SCREENSHOT.png]
// Exit status 0 when every check passed; each check prints "ok" or "not ok" (TAP).
import { execFileSync } from 'node:child_process';
import { mkdtempSync, rmSync, writeFileSync, existsSync } from 'node:fs';
import http from 'node:http';
import { tmpdir } from 'node:os';
import path from 'node:path';
import { chromiumPath as chromium, launchChromium, start as spawnKept, until } from './harness.mjs';

const build = path.resolve(process.argv[2] || 'build/default');
const screenshotPath = process.argv[3] || '';
const port = 47950 + (process.pid % 40);  // the daemon's gaze port; the monitor takes any free one
const dir = mkdtempSync(path.join(tmpdir(), 'fovea-browser-'));
const children = [];
let failures = 0;
let checks = 0;

function check(ok, what, detail = '') {
  checks += 1;
  if (!ok) failures += 1;
  console.log(`${ok ? 'ok' : 'not ok'} ${checks} - ${what}${detail ? ` (${detail})` : ''}`);
}

function start(program, args) {
  const child = spawnKept(program, args);
  children.push(child);
  return child;
}

// A raw HTTP request (upgrade or not); resolves with the status code.
function request(monitorPort, target, headers) {
  return new Promise((resolve, reject) => {
    const req = http.request({ host: '127.0.0.1', port: monitorPort, path: target, headers, setHost: !headers.Host });
    req.on('response', (res) => { res.resume(); resolve(res.statusCode); });
    req.on('upgrade', (res, socket) => { socket.destroy(); resolve(res.statusCode); });
    req.on('error', reject);
    req.end();
  });
}

const wsHeaders = (extra) => ({
  Connection: 'Upgrade', Upgrade: 'websocket', 'Sec-WebSocket-Version': '13',
  'Sec-WebSocket-Key': 'dGhlIHNhbXBsZSBub25jZQ==', ...extra,
});

async function main() {
  for (const p of [chromium, `${build}/trackerd/fovea-trackerd`, `${build}/monitor/fovea-monitor`]) {
    if (!existsSync(p)) throw new Error(`${p} is missing (chromium: deploy/install-deps.sh; programs: build first)`);
  }
  const control = path.join(dir, 'control.sock');
  // A screen-space calibration (the identity) with a validation of four targets, as fovea-calibrate
  // writes it: the page draws its error vectors.
  const calibration = path.join(dir, 'calibration.json');
  const points = [[480, 270, 12, -8], [1440, 270, -10, -14], [480, 810, 6, 11], [1440, 810, -15, 9]];
  writeFileSync(calibration, JSON.stringify({
    format: 'fovea-calibration', version: 1, model: { kind: 'affine', a: [0, 1, 0, 0, 0, 1] }, input: 'screen',
    points_used: 9, outliers_rejected: 0, rms_residual: 0, condition: 1, created: '2026-12-01T00:00:00Z',
    display: { width_px: 1920, height_px: 1080, width_mm: 531.3, height_mm: 298.9, distance_mm: 650 },
    validation: {
      targets: 4, samples: 400, lost: 0, accuracy_deg: 0.52, date: '2026-12-01T00:00:00Z',
      points: points.map(([x, y, ex, ey]) => ({ target_px: [x, y], mean_error_px: [ex, ey], accuracy_deg: 0.5 })),
    },
  }));
  const daemon = start(`${build}/trackerd/fovea-trackerd`,
    ['--source', 'synthetic-eye', '--port', String(port), '--control-socket', control, '--calibration', calibration]);
  await until('the daemon', () => existsSync(control));
  const monitor = start(`${build}/monitor/fovea-monitor`,
    ['--server', `127.0.0.1:${port}`, '--control-socket', control, '--listen', '127.0.0.1:0']);
  const url = await until('the monitor\'s URL', () => (monitor.output.match(/open (http:\/\/\S+)/) || [])[1]);
  const monitorPort = Number(new URL(url).port);
  const token = new URL(url).searchParams.get('token');
  check(/^[0-9a-f]{32}$/.test(token), 'the printed URL holds a 128-bit token', url.replace(token, '…'));

  // ---- refused requests --------------------------------------------------------------------------
  check(await request(monitorPort, '/', { Host: `evil.example:${monitorPort}` }) === 421, 'a request for another Host is refused (DNS rebinding)');
  check(await request(monitorPort, `/ws?token=${token}`, wsHeaders({ Origin: 'http://evil.example' })) === 403,
    'a WebSocket from another origin is refused (cross-site WebSocket hijacking)');
  check(await request(monitorPort, '/ws?token=0123', wsHeaders({ Origin: `http://127.0.0.1:${monitorPort}` })) === 403,
    'a WebSocket with a wrong token is refused');
  check(await request(monitorPort, `/ws?token=${token}`, wsHeaders({ Origin: `http://127.0.0.1:${monitorPort}` })) === 101,
    'the WebSocket with this origin and the token is accepted');

  // ---- the page ----------------------------------------------------------------------------------
  const browser = await launchChromium(dir);
  try {
    const page = await browser.newPage();
    const pageErrors = [];
    page.on('pageerror', (e) => pageErrors.push(String(e)));
    page.on('console', (m) => { if (m.type() === 'error') pageErrors.push(m.text()); });
    await page.setViewport({ width: 1280, height: 900 });
    await page.goto(url, { waitUntil: 'load' });
    // The state, and when the page read it (its own clock).
    const state = () => page.evaluate(() => ({ ...JSON.parse(JSON.stringify(window.foveaMonitor.state)), at: performance.now() }));
    const a = await until('eye frames and gaze in the page', async () => {
      const s = await state();
      return s.eye_frames >= 5 && s.samples >= 100 && s.status.source && s.daemon.source ? s : null;
    });
    await new Promise((r) => setTimeout(r, 2000));
    const b = await state();
    const seconds = (b.at - a.at) / 1000;
    check(b.eye_frames > a.eye_frames, 'the eye image updates', `${a.eye_frames} -> ${b.eye_frames} frames`);
    // At most 30 Hz from the daemon (a sanitizer build's daemon renders the synthetic eye slower),
    // counted over the frames' own capture times: by the page's clock a backlog that a loaded
    // machine delivers at once after a stall reads as a burst (69 in 2.02 s once, in CI).
    const eyeSeconds = (b.eye_t_ms - a.eye_t_ms) / 1000;
    const eyeRate = (b.eye_frames - a.eye_frames) / eyeSeconds;
    check(eyeSeconds > 0.5 && eyeRate >= 5 && eyeRate <= 33, 'eye images arrive, at most 30 a second',
      `${b.eye_frames - a.eye_frames} frames captured over ${eyeSeconds.toFixed(2)} s (read ${seconds.toFixed(2)} s apart)`);
    check(b.pupil !== null && b.confidence > 0.5, 'the pupil is found and drawn', JSON.stringify(b.pupil));
    // 120 Hz from a release daemon; a sanitizer build's renders the synthetic eye at about 25 Hz
    // alone and 13 Hz beside the rest of its suite (ctest -j): at least 5 Hz, as the eye images.
    check(b.samples - a.samples >= 5 * seconds, 'gaze samples keep coming', `${a.samples} -> ${b.samples} in ${seconds.toFixed(2)} s`);
    check(b.gaze && a.gaze && (b.gaze.x !== a.gaze.x || b.gaze.y !== a.gaze.y), 'the gaze moves',
      `(${a.gaze.x.toFixed(0)}, ${a.gaze.y.toFixed(0)}) -> (${b.gaze.x.toFixed(0)}, ${b.gaze.y.toFixed(0)}) px`);
    const labels = Object.keys(b.labels_seen).filter((k) => b.labels_seen[k] > 0);
    check(labels.includes('fixation') && labels.includes('saccade'), 'the labels change (fixations and saccades)', labels.join(', '));
    check(b.latency.count > 10 && b.latency.p99_ms > 0 && b.latency.p99_ms < 1000, 'the page measures its update latency',
      `p50 ${b.latency.p50_ms?.toFixed(1)} ms, p99 ${b.latency.p99_ms?.toFixed(1)} ms`);

    // ---- STATUS against fovea-ctl status ------------------------------------------------------------
    const ctl = execFileSync(`${build}/trackerd/fovea-ctl`, ['status', '--server', `127.0.0.1:${port}`]).toString();
    const source = (ctl.match(/^source\s+(.*) \((\w+)\)$/m) || [])[1];
    const rate = Number((ctl.match(/^rate\s+([\d.]+) Hz/m) || [])[1]);
    check(source === b.status.source, 'the page\'s source is fovea-ctl status\'s', `${source} | ${b.status.source}`);
    check(rate === b.status.nominal_rate_hz, 'the page\'s nominal rate is fovea-ctl status\'s', `${rate} | ${b.status.nominal_rate_hz}`);
    check(b.daemon.calibration && b.daemon.calibration.description.includes('calibration.json'), 'the daemon\'s calibration is shown',
      b.daemon.calibration?.description);
    const validationText = await page.$eval('#validation-info', (e) => e.textContent);
    check(validationText.startsWith('4 targets') && validationText.includes('0.52'), 'the validation figure is drawn', validationText);

    // ---- controls ---------------------------------------------------------------------------------
    check(b.controls === true, 'the controls show for a user of the control socket');
    await page.type('#marker-label', 'browser-test');
    await page.click('#mark');
    const reply = await until('the marker\'s reply', async () => (await state()).last_reply);
    check(reply.ok === true, 'a marker sent from the page is accepted', reply.message);

    // ---- the screenshot -------------------------------------------------------------------------
    const png = await page.screenshot({ type: 'png', fullPage: true });
    if (screenshotPath) writeFileSync(screenshotPath, png);
    const seen = await page.evaluate(async (b64) => {
      const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
      const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
      const c = new OffscreenCanvas(bitmap.width, bitmap.height);
      const g = c.getContext('2d');
      g.drawImage(bitmap, 0, 0);
      const count = (id, match) => {
        const r = document.getElementById(id).getBoundingClientRect();
        const d = g.getImageData(Math.round(r.left + scrollX), Math.round(r.top + scrollY), Math.round(r.width), Math.round(r.height)).data;
        let n = 0, sum = 0, sum2 = 0;
        for (let i = 0; i < d.length; i += 4) {
          if (match(d[i], d[i + 1], d[i + 2])) n += 1;
          const v = d[i + 1]; sum += v; sum2 += v * v;
        }
        const px = d.length / 4;
        return { n, spread: Math.sqrt(sum2 / px - (sum / px) ** 2) };
      };
      const green = (r, gr, bl) => gr > 150 && r < 90 && bl < 140;  // the pupil ellipse, #22c55e
      const anyLabel = (r, gr, bl) => (bl > 200 && r < 100) || (r > 200 && gr < 100) || (gr > 150 && r < 90);
      const red = (r, gr, bl) => r > 200 && gr < 160 && bl < 160;  // the error vectors, #f87171
      return { eye: count('eye', green), screen: count('screen', anyLabel), validation: count('validation', red) };
    }, png.toString('base64'));
    check(seen.eye.spread > 10, 'the screenshot shows an eye image (not a blank canvas)', `grey spread ${seen.eye.spread.toFixed(1)}`);
    check(seen.eye.n > 30, 'the screenshot shows the pupil ellipse over the eye', `${seen.eye.n} green pixels`);
    check(seen.screen.n > 20, 'the screenshot shows the gaze trail on the screen', `${seen.screen.n} label-coloured pixels`);
    check(seen.validation.n > 20, 'the screenshot shows the validation\'s error vectors', `${seen.validation.n} red pixels`);
    check(pageErrors.length === 0, 'the page ran without errors (CSP violations included)', pageErrors.join('; '));

    // ---- a user outside the daemon's group --------------------------------------------------------
    // As root the test can be someone else: `nobody` may not use the control or viewer sockets. Its
    // monitor shows gaze and STATUS, says why there are no eye images, and shows no controls.
    if (process.getuid() === 0 && existsSync('/usr/bin/setpriv')) {
      const other = start('/usr/bin/setpriv', ['--reuid=nobody', '--regid=nogroup', '--clear-groups', '--',
        `${build}/monitor/fovea-monitor`, '--server', `127.0.0.1:${port}`, '--control-socket', control, '--listen', '127.0.0.1:0']);
      const otherUrl = await until('the second monitor\'s URL', () => (other.output.match(/open (http:\/\/\S+)/) || [])[1]);
      const p2 = await browser.newPage();
      await p2.goto(otherUrl, { waitUntil: 'load' });
      const s2 = await until('gaze and status on the read-only page', async () => {
        const s = await p2.evaluate(() => JSON.parse(JSON.stringify(window.foveaMonitor.state)));
        return s.samples > 50 && s.status.viewer_feed ? s : null;
      });
      check(s2.controls === false && await p2.$eval('#controls', (e) => e.hidden), 'a user without the control socket gets no controls');
      check(s2.eye_frames === 0 && /permission denied/.test(s2.status.viewer_feed),
        'a user outside the daemon\'s group sees no eye images, and the page says why', s2.status.viewer_feed);
      await p2.close();
    } else {
      console.log('# skipped the other-user checks: not root, or no setpriv');
    }
  } finally {
    await browser.close();
  }
  check(daemon.exitCode === null, 'the daemon is still running');
}

try {
  await main();
} catch (e) {
  check(false, 'the test ran to its end', e.message);
} finally {
  for (const c of children) c.kill('SIGTERM');
  await new Promise((r) => setTimeout(r, 300));
  if (failures > 0) {
    for (const c of children) console.log(`# ${c.spawnargs[0]}:\n# ${c.output.split('\n').slice(-15).join('\n# ')}`);
  }
  rmSync(dir, { recursive: true, force: true });
}
console.log(`1..${checks}`);
process.exit(failures === 0 ? 0 : 1);
