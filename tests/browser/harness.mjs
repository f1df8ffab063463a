// SPDX-License-Identifier: Apache-2.0
// What the browser test and bench/bench_monitor.mjs share: child processes whose output is kept,
// waiting for a condition, and Debian's chromium launched headless for this machine (no sandbox as
// root, no GPU, no background network: the machine reaches no outside host).
import { spawn } from 'node:child_process';
import path from 'node:path';
import puppeteer from 'puppeteer-core';

export const chromiumPath = process.env.FOVEA_CHROMIUM || '/usr/bin/chromium';

// Starts `program`; its stdout and stderr collect in child.output.
export function start(program, args) {
  const child = spawn(program, args, { stdio: ['ignore', 'pipe', 'pipe'] });
  child.output = '';
  child.stdout.on('data', (d) => { child.output += d; });
  child.stderr.on('data', (d) => { child.output += d; });
  return child;
}

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// Polls `condition` (sync or async) every 100 ms until it returns something truthy, which it returns.
export async function until(what, condition, ms = 15000) {
  const end = Date.now() + ms;
  while (Date.now() < end) {
    const v = await condition();
    if (v) return v;
    await sleep(100);
  }
  throw new Error(`timed out waiting for ${what}`);
}

export function launchChromium(dir) {
  return puppeteer.launch({
    executablePath: chromiumPath,
    headless: true,
    userDataDir: path.join(dir, 'profile'),
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync'],
  });
}
