// SPDX-License-Identifier: Apache-2.0
// What fovea-monitor costs (issue 45 "Measure"), side by side in one run on a noisy machine:
// a daemon with SOURCE at RATE Hz (synthetic-eye: gaze and eye frames at that rate, the viewer
// feed sending at most 30 frames a second; synthetic: gaze only), one ordinary client (fovea-ctl
// watch) measuring its gaze latency, and, in alternate windows, fovea-monitor with one page open
// in headless chromium.
// Per window: the daemon's CPU (utime + stime from /proc, % of one core), the client's gaze
// latency p50/p99, and with the monitor its own CPU and the page's update latency (the daemon's
// sample to drawn, from the page's own timestamps: window.foveaMonitor.state.latency) and the eye
// image's.
//
// Usage: node bench/bench_monitor.mjs [--build build/default] [--source synthetic-eye|synthetic] [--rate 120]
//                                     [--baseline none|extra-client] [--page chromium|none] [--pin] [--daemon-nice N]
//                                     [--pairs 3] [--seconds 10] [--csv FILE]
import { execFileSync } from 'node:child_process';
import { existsSync, mkdtempSync, readdirSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import path from 'node:path';
import { launchChromium, sleep, start, until } from '../tests/browser/harness.mjs';

const arg = (name, fallback) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : fallback;
};
const build = path.resolve(arg('build', 'build/default'));
const source = arg('source', 'synthetic-eye');
const rate = Number(arg('rate', '120'));
const pairs = Number(arg('pairs', '3'));
const seconds = Number(arg('seconds', '10'));
const csvPath = arg('csv', '');
// --baseline none: the monitor-off windows have the measuring client alone; extra-client: a second
// plain subscriber (fovea-ctl watch) stands where the monitor would, so that the difference is
// what the monitor costs beyond being one more subscriber.
const baseline = arg('baseline', 'none');
// --page chromium: a page open in headless chromium while the monitor is attached; none: the
// monitor alone (what it costs the daemon without a browser competing for this machine's cores).
const pageMode = arg('page', 'chromium');
// --pin: the daemon on CPU 0 and chromium on CPU 1 (taskset), as if the browser ran on another
// machine; the monitor and the measuring client go where the scheduler puts them.
const pin = process.argv.includes('--pin');
// --daemon-nice N: the daemon at this nice value (negative: before the browser), as a service unit's
// Nice= would run it.
const daemonNice = Number(arg('daemon-nice', '0'));
const port = 47870;
const dir = mkdtempSync(path.join(tmpdir(), 'fovea-bench-monitor-'));
const ticks = 100;  // USER_HZ on Linux

function cpuSeconds(pid) {
  const f = readFileSync(`/proc/${pid}/stat`, 'utf8');
  const fields = f.slice(f.lastIndexOf(')') + 2).split(' ');
  return (Number(fields[11]) + Number(fields[12])) / ticks;  // utime, stime
}
// The browser's processes (browser, zygotes, renderers, GPU, utility).
function browserPids() {
  const pids = [];
  for (const pid of readdirSync('/proc')) {
    if (!/^\d+$/.test(pid)) continue;
    try {
      if (readFileSync(`/proc/${pid}/cmdline`, 'utf8').startsWith('/usr/lib/chromium/')) pids.push(pid);
    } catch {
      // gone meanwhile
    }
  }
  return pids;
}
// What the page costs this machine: all of the browser's processes together.
function browserSeconds() {
  let total = 0;
  for (const pid of browserPids()) {
    try {
      total += cpuSeconds(pid);
    } catch {
      // gone meanwhile
    }
  }
  return total;
}
// One window: a fresh `fovea-ctl watch` for the client's latency; the daemon's CPU over it.
async function window(daemon, withMonitor, browser) {
  let monitor = null, page = null, extra = null;
  if (!withMonitor && baseline === 'extra-client') {
    extra = start(`${build}/trackerd/fovea-ctl`, ['watch', '--server', `127.0.0.1:${port}`, '--every', '1000000']);
    await sleep(1000);
  }
  if (withMonitor) {
    monitor = start(`${build}/monitor/fovea-monitor`,
      ['--server', `127.0.0.1:${port}`, '--control-socket', path.join(dir, 'control.sock'), '--listen', '127.0.0.1:0']);
    const url = await until('the monitor', () => (monitor.output.match(/open (http:\/\/\S+)/) || [])[1]);
    if (pageMode === 'none') {
      await sleep(1500);
    } else {
      page = await browser.newPage();
      await page.goto(url);
      await until('gaze (and eye frames) on the page', () => page.evaluate(
        (eye) => window.foveaMonitor.state.samples > 100 && (!eye || window.foveaMonitor.state.eye_frames > 10), source === 'synthetic-eye'));
      await sleep(1000);
    }
  }
  const stats = path.join(dir, `watch-${Date.now()}.json`);
  const watch = start(`${build}/trackerd/fovea-ctl`,
    ['watch', '--server', `127.0.0.1:${port}`, '--every', '1000000', '--duration', String(seconds), '--stats-json', stats]);
  await sleep(500);  // subscribed
  const d0 = cpuSeconds(daemon.pid), m0 = monitor ? cpuSeconds(monitor.pid) : 0, b0 = browserSeconds(), t0 = Date.now();
  const lat0 = page ? await page.evaluate(() => JSON.parse(JSON.stringify(window.foveaMonitor.state))) : null;
  await new Promise((r) => watch.on('exit', r));
  const span = (Date.now() - t0) / 1000;
  const row = {
    monitor: withMonitor ? 1 : 0,
    daemon_cpu_pct: (100 * (cpuSeconds(daemon.pid) - d0)) / span,
    monitor_cpu_pct: monitor ? (100 * (cpuSeconds(monitor.pid) - m0)) / span : '',
    browser_cpu_pct: (100 * (browserSeconds() - b0)) / span,
  };
  const w = JSON.parse(readFileSync(stats, 'utf8'));
  row.client_samples = w.received;
  row.client_lost = w.lost;
  row.client_latency_p50_ms = w.latency_p50_ns / 1e6;
  row.client_latency_p99_ms = w.latency_p99_ns / 1e6;
  if (monitor && !page) {
    monitor.kill('SIGTERM');
    await new Promise((r) => monitor.on('exit', r));
  }
  if (page) {
    const s = await page.evaluate(() => JSON.parse(JSON.stringify(window.foveaMonitor.state)));
    row.page_samples = s.samples - lat0.samples;
    row.page_eye_frames_per_s = (s.eye_frames - lat0.eye_frames) / span;
    row.page_latency_p50_ms = s.latency.p50_ms;
    row.page_latency_p99_ms = s.latency.p99_ms;
    row.eye_latency_p50_ms = s.eye_latency.p50_ms;
    row.eye_latency_p99_ms = s.eye_latency.p99_ms;
    await page.close();
    monitor.kill('SIGTERM');
    await new Promise((r) => monitor.on('exit', r));
  }
  if (extra) {
    extra.kill('SIGTERM');
    await new Promise((r) => extra.on('exit', r));
  }
  return row;
}

async function main() {
  for (const p of [`${build}/trackerd/fovea-trackerd`, `${build}/monitor/fovea-monitor`, '/usr/bin/chromium']) {
    if (!existsSync(p)) throw new Error(`${p} is missing`);
  }
  const daemonArgs = ['--source', source, '--rate', String(rate), '--port', String(port), '--control-socket',
    path.join(dir, 'control.sock')];
  // nice execs the daemon: the child's pid is the daemon's.
  const daemon = daemonNice !== 0
    ? start('nice', ['-n', String(daemonNice), `${build}/trackerd/fovea-trackerd`, ...daemonArgs])
    : start(`${build}/trackerd/fovea-trackerd`, daemonArgs);
  await until('the daemon', () => existsSync(path.join(dir, 'control.sock')));
  const browser = await launchChromium(dir);
  if (pin) {
    // Renderers fork from the zygotes later and inherit their affinity.
    execFileSync('taskset', ['-a', '-cp', '0', String(daemon.pid)]);
    for (const pid of browserPids()) execFileSync('taskset', ['-a', '-cp', '1', pid]);
  }
  const rows = [];
  try {
    await sleep(2000);  // the daemon settles
    for (let k = 0; k < pairs; k += 1) {
      for (const m of [false, true]) {
        const r = await window(daemon, m, browser);
        rows.push(r);
        console.log(JSON.stringify(r));
      }
    }
  } finally {
    await browser.close();
    daemon.kill('SIGTERM');
    await sleep(300);
    rmSync(dir, { recursive: true, force: true });
  }
  const keys = Object.keys(rows[1]);
  const csv = [keys.join(',')].concat(rows.map((r) => keys.map((k) => (r[k] === undefined ? '' : typeof r[k] === 'number' ? +r[k].toFixed(3) : r[k])).join(','))).join('\n') + '\n';
  if (csvPath) writeFileSync(csvPath, csv);
  const mean = (m, key) => { const v = rows.filter((r) => r.monitor === m).map((r) => r[key]); return v.reduce((a, b) => a + b, 0) / v.length; };
  const median = (key) => { const v = rows.filter((r) => r.monitor === 1).map((r) => r[key]).sort((a, b) => a - b); return v[Math.floor(v.length / 2)]; };
  console.log(`\n${source} at ${rate} Hz, ${pairs} pairs of ${seconds} s windows (monitor off${baseline === 'extra-client' ? ', a second plain client instead' : ''} / on${pageMode === 'none' ? ', no page open' : ', a page open in chromium'}${pin ? '; daemon on CPU 0, chromium on CPU 1' : ''}${daemonNice ? `; daemon at nice ${daemonNice}` : ''}):`);
  console.log(`samples to the client ${mean(0, 'client_samples').toFixed(0)} -> ${mean(1, 'client_samples').toFixed(0)} per window, ` +
    `lost ${mean(0, 'client_lost')} -> ${mean(1, 'client_lost')}`);
  console.log(`daemon CPU            ${mean(0, 'daemon_cpu_pct').toFixed(1)} % -> ${mean(1, 'daemon_cpu_pct').toFixed(1)} % of a core ` +
    `(monitor attached: ${(mean(1, 'daemon_cpu_pct') - mean(0, 'daemon_cpu_pct')).toFixed(2)} points)`);
  console.log(`client gaze p99       ${mean(0, 'client_latency_p99_ms').toFixed(3)} ms -> ${mean(1, 'client_latency_p99_ms').toFixed(3)} ms ` +
    `(p50 ${mean(0, 'client_latency_p50_ms').toFixed(3)} -> ${mean(1, 'client_latency_p50_ms').toFixed(3)})`);
  console.log(`monitor CPU           ${mean(1, 'monitor_cpu_pct').toFixed(1)} % of a core`);
  console.log(`browser CPU           ${mean(0, 'browser_cpu_pct').toFixed(1)} % -> ${mean(1, 'browser_cpu_pct').toFixed(1)} % of a core (all of chromium's processes)`);
  if (pageMode === 'none') return;
  console.log(`page update latency   p50 ${median('page_latency_p50_ms').toFixed(1)} ms, p99 ${median('page_latency_p99_ms').toFixed(1)} ms (median over windows)`);
  if (source === 'synthetic-eye') console.log(`eye image latency     p50 ${median('eye_latency_p50_ms').toFixed(1)} ms, p99 ${median('eye_latency_p99_ms').toFixed(1)} ms; ` +
    `${mean(1, 'page_eye_frames_per_s').toFixed(1)} eye images/s drawn`);
}

main().catch((e) => { console.error(e.message); process.exit(1); });
