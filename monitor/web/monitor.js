// SPDX-License-Identifier: Apache-2.0
// fovea-monitor's page. Received data is parsed as JSON and drawn or set as text (textContent);
// nothing received is ever run as code or inserted as HTML (the Content-Security-Policy forbids
// it as well). The latest state is kept in window.foveaMonitor.state (MONITOR.md "Test contract").
'use strict';

(() => {
  const LABELS = ['unknown', 'fixation', 'saccade', 'pursuit', 'blink'];
  const COLOURS = { unknown: '#9ca3af', fixation: '#3b82f6', saccade: '#ef4444', pursuit: '#22c55e', blink: '#f59e0b' };
  const TRAIL_MS = 1500;
  const TIMELINE_MS = 5000;
  const KEEP_MS = 6000;
  // The gaze panels are redrawn at most this often: at 60 Hz, software-rendered canvases (a browser
  // without a GPU) cost the machine that also runs the daemon twice as much, for motion the eye
  // barely tells apart.
  const GAZE_DRAW_HZ = 30;
  let lastGazeDraw = 0;

  const state = {
    connected: false, samples: 0, gaze: null, label: 'unknown', valid: false, eye_frames: 0, pupil: null,
    confidence: null, detect_ms: null, eye_t_ms: null, controls: false, events: 0, provisional_events: 0, last_event: null,
    status: {}, daemon: {}, latency: { p50_ms: null, p99_ms: null, count: 0 }, eye_latency: { p50_ms: null, p99_ms: null, count: 0 },
    measured_rate_hz: null, last_reply: null, errors: 0, labels_seen: {},
  };
  window.foveaMonitor = { state };

  const $ = (id) => document.getElementById(id);
  const samples = [];  // {t, x, y, xd, yd, v, label, valid}
  const marks = [];    // provisional events and markers: {t, x, y, kind, what}
  let display = { width_px: 1920, height_px: 1080 };
  let eye = null;      // {bitmap, meta}
  let dirty = { eye: false, gaze: false, status: false, validation: false };
  const latencies = [];
  const eyeLatencies = [];
  let pendingLatency = null;
  let pendingEyeLatency = null;

  // ---- the connection ---------------------------------------------------------------------------

  function connect() {
    const token = new URLSearchParams(location.search).get('token') || '';
    const ws = new WebSocket(`ws://${location.host}/ws?token=${encodeURIComponent(token)}`);
    ws.binaryType = 'arraybuffer';
    ws.onopen = () => { state.connected = true; setBadge('connection', 'on', 'live'); };
    ws.onclose = () => {
      state.connected = false;
      setBadge('connection', 'off', token ? 'disconnected: retrying' : 'no token in the URL: open the URL fovea-monitor printed');
      setTimeout(connect, 1000);
    };
    ws.onmessage = (m) => {
      try {
        if (typeof m.data === 'string') onText(JSON.parse(m.data)); else onEyeFrame(m.data);
      } catch (e) {
        state.errors += 1;
      }
    };
    wireControls(ws);
  }

  function onText(msg) {
    switch (msg.type) {
      case 'hello': state.controls = msg.controls === true; $('controls').hidden = !state.controls; break;
      case 'gaze': onGaze(msg); break;
      case 'status': state.status = msg; if (msg.display) display = msg.display; dirty.status = true; break;
      case 'daemon': state.daemon = msg.status || {}; dirty.status = true; dirty.validation = true; break;
      case 'reply': state.last_reply = msg; $('reply').textContent = `${msg.command}: ${msg.ok ? 'ok' : 'failed'}: ${msg.message || ''}`; break;
      default: break;
    }
  }

  function onGaze(msg) {
    for (const r of msg.samples) {
      const s = { t: r[0], x: r[1], y: r[2], xd: r[3], yd: r[4], v: r[5], label: LABELS[r[6]] || 'unknown', valid: r[7] === 1 };
      samples.push(s);
      state.samples += 1;
      state.labels_seen[s.label] = (state.labels_seen[s.label] || 0) + 1;
    }
    const newest = samples[samples.length - 1];
    if (newest) {
      state.valid = newest.valid;
      state.label = newest.label;
      state.gaze = { x: newest.x * display.width_px, y: newest.y * display.height_px };
      const cut = newest.t - KEEP_MS;
      let drop = 0;
      while (drop < samples.length && samples[drop].t < cut) drop += 1;
      if (drop > 0) samples.splice(0, drop);
    }
    for (const e of msg.events) {
      if (e.provisional || e.retracted) state.provisional_events += 1; else state.events += 1;
      state.last_event = e;
      if (e.provisional || e.retracted) marks.push({ t: e.t_ms + e.duration_ms, x: e.x, y: e.y, kind: e.kind, what: e.retracted ? 'retracted' : 'provisional' });
    }
    for (const m of msg.markers) marks.push({ t: m.t_ms, kind: 'marker', what: m.label });
    while (marks.length > 200) marks.shift();
    // The oldest batch not yet drawn: its samples waited longest.
    if (msg.age_ms !== null && msg.samples.length > 0 && pendingLatency === null) {
      pendingLatency = { age: msg.age_ms, sent: msg.sent_unix_ms };
    }
    dirty.gaze = true;
  }

  function onEyeFrame(buffer) {
    const view = new DataView(buffer);
    const n = view.getUint32(0, true);
    if (n + 4 > buffer.byteLength) return;
    const meta = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, n)));
    const blob = new Blob([new Uint8Array(buffer, 4 + n)], { type: 'image/jpeg' });
    createImageBitmap(blob).then((bitmap) => {
      if (eye && eye.bitmap) eye.bitmap.close();
      eye = { bitmap, meta };
      state.eye_frames += 1;
      if (state.eye_t_ms === null || meta.t_ms > state.eye_t_ms) state.eye_t_ms = meta.t_ms;
      state.pupil = meta.pupil ? { x: meta.pupil[0], y: meta.pupil[1] } : null;
      state.confidence = meta.confidence;
      state.detect_ms = meta.detect_ms;
      if (meta.age_ms !== undefined && pendingEyeLatency === null) pendingEyeLatency = { age: meta.age_ms, sent: meta.sent_unix_ms };
      dirty.eye = true;
    }).catch(() => { state.errors += 1; });
  }

  function wireControls(ws) {
    const send = (obj) => { if (ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(obj)); };
    $('mark').onclick = () => send({ type: 'mark', label: $('marker-label').value || 'mark' });
    $('record-start').onclick = () => send({ type: 'record-start', path: $('record-path').value });
    $('record-stop').onclick = () => send({ type: 'record-stop' });
  }

  // ---- drawing ----------------------------------------------------------------------------------

  function frame() {
    requestAnimationFrame(frame);
    if (dirty.eye) { drawEye(); dirty.eye = false; }
    const t = performance.now();
    if (dirty.gaze && t - lastGazeDraw >= 1000 / GAZE_DRAW_HZ - 4) {
      drawScreen(); drawTimeline(); dirty.gaze = false; lastGazeDraw = t;
    }
    if (dirty.status) { drawStatus(); dirty.status = false; }
    if (dirty.validation) { drawValidation(); dirty.validation = false; }
    // Drawn: the page's part of the latency ends here, on the same clock the monitor stamped.
    const now = performance.timeOrigin + performance.now();
    if (pendingLatency && !dirty.gaze) { record(latencies, pendingLatency.age + (now - pendingLatency.sent), state.latency); pendingLatency = null; }
    if (pendingEyeLatency) { record(eyeLatencies, pendingEyeLatency.age + (now - pendingEyeLatency.sent), state.eye_latency); pendingEyeLatency = null; }
  }

  function record(list, ms, out) {
    list.push(ms);
    if (list.length > 2000) list.shift();
    out.count += 1;
    if (out.count % 10 === 0 || list.length < 10) {
      const sorted = list.slice().sort((a, b) => a - b);
      out.p50_ms = sorted[Math.floor(0.5 * (sorted.length - 1))];
      out.p99_ms = sorted[Math.floor(0.99 * (sorted.length - 1))];
    }
  }

  function drawEye() {
    const c = $('eye');
    const g = c.getContext('2d');
    const { bitmap, meta } = eye;
    if (c.width !== meta.width * 2 || c.height !== meta.height * 2) { c.width = meta.width * 2; c.height = meta.height * 2; }
    const s = c.width / meta.source_width;  // camera pixels -> canvas
    g.drawImage(bitmap, 0, 0, c.width, c.height);
    g.lineWidth = 2;
    if (meta.roi[2] > 0) {
      g.setLineDash([6, 4]);
      g.strokeStyle = meta.used_roi ? '#facc15' : '#a3a3a3';
      g.strokeRect(meta.roi[0] * s, meta.roi[1] * s, meta.roi[2] * s, meta.roi[3] * s);
      g.setLineDash([]);
    }
    if (meta.pupil) {
      const [x, y, major, minor, angle] = meta.pupil;
      g.strokeStyle = meta.confidence >= 0.5 ? '#22c55e' : '#f97316';
      g.beginPath();
      g.ellipse(x * s, y * s, Math.max(1, major * s / 2), Math.max(1, minor * s / 2), angle * Math.PI / 180, 0, 2 * Math.PI);
      g.stroke();
      g.beginPath();
      g.moveTo(x * s - 5, y * s); g.lineTo(x * s + 5, y * s); g.moveTo(x * s, y * s - 5); g.lineTo(x * s, y * s + 5);
      g.stroke();
    }
    g.strokeStyle = '#22d3ee';
    for (const [gx, gy] of meta.glints) {
      g.beginPath();
      g.arc(gx * s, gy * s, 4, 0, 2 * Math.PI);
      g.stroke();
    }
    const what = meta.pupil ? `pupil (${meta.pupil[0].toFixed(1)}, ${meta.pupil[1].toFixed(1)}) px, confidence ${meta.confidence.toFixed(2)}`
      : (meta.blink ? 'no pupil (blink or lost)' : 'no pupil');
    $('eye-info').textContent = `${what}; ${meta.glints.length} glints${meta.glint_valid ? '' : ' (no pupil-glint vector)'}; ` +
      `detector ${meta.detect_ms.toFixed(2)} ms; frame ${meta.frame} (${meta.source_width}x${meta.source_height}, shown ${meta.width}x${meta.height})`;
  }

  function screenScale(c) {
    const aspect = display.height_px / display.width_px;
    const h = Math.round(c.width * aspect);
    if (c.height !== h) c.height = h;
    return c.width / display.width_px;
  }

  // A screen-shaped panel, cleared: its canvas, context and the scale from screen pixels.
  function screenPanel(id) {
    const c = $(id);
    const g = c.getContext('2d');
    const s = screenScale(c);
    g.fillStyle = '#0b0d10';
    g.fillRect(0, 0, c.width, c.height);
    return { c, g, s };
  }

  function drawScreen() {
    const { c, g, s } = screenPanel('screen');
    g.strokeStyle = '#374151';
    g.strokeRect(0.5, 0.5, c.width - 1, c.height - 1);
    const newest = samples[samples.length - 1];
    if (!newest) return;
    const from = newest.t - TRAIL_MS;
    // One path per run of samples with the same label and fade step (at 1 kHz, 1,500 samples make
    // a few dozen strokes, not 1,500).
    let prev = null, key = null;
    g.beginPath();
    for (const p of samples) {
      if (p.t < from || !p.valid) { prev = null; continue; }
      const x = p.x * display.width_px * s, y = p.y * display.height_px * s;
      const fade = Math.floor(8 * (p.t - from) / TRAIL_MS);
      const k = `${p.label}/${fade}`;
      if (k !== key) {
        g.stroke();
        g.strokeStyle = COLOURS[p.label];
        g.globalAlpha = 0.25 + 0.75 * fade / 8;
        g.beginPath();
        if (prev) g.moveTo(prev[0], prev[1]);
        key = k;
      }
      if (prev) g.lineTo(x, y); else g.moveTo(x, y);
      prev = [x, y];
    }
    g.stroke();
    g.globalAlpha = 1;
    for (const m of marks) {
      if (m.t < from || m.x === undefined) continue;
      const x = m.x * display.width_px * s, y = m.y * display.height_px * s;
      g.strokeStyle = COLOURS[m.kind] || '#fff';
      g.setLineDash(m.what === 'provisional' ? [3, 3] : []);
      g.beginPath(); g.arc(x, y, 9, 0, 2 * Math.PI); g.stroke();
      if (m.what === 'retracted') { g.beginPath(); g.moveTo(x - 6, y - 6); g.lineTo(x + 6, y + 6); g.stroke(); }
      g.setLineDash([]);
    }
    if (newest.valid) {
      g.fillStyle = COLOURS[newest.label];
      g.beginPath(); g.arc(newest.x * display.width_px * s, newest.y * display.height_px * s, 7, 0, 2 * Math.PI); g.fill();
    }
    const gz = state.gaze;
    $('gaze-info').textContent = newest.valid
      ? `${state.label} at (${gz.x.toFixed(0)}, ${gz.y.toFixed(0)}) px, (${newest.xd.toFixed(2)}°, ${newest.yd.toFixed(2)}°), ${newest.v.toFixed(0)}°/s`
      : 'gaze invalid (no calibration, blink or lost)';
  }

  function drawTimeline() {
    const c = $('timeline');
    if (c.width !== c.clientWidth && c.clientWidth > 0) c.width = c.clientWidth;
    const g = c.getContext('2d');
    const w = c.width, h = c.height;
    g.fillStyle = '#0b0d10';
    g.fillRect(0, 0, w, h);
    const newest = samples[samples.length - 1];
    if (!newest) return;
    const t1 = newest.t, t0 = t1 - TIMELINE_MS;
    const X = (t) => (t - t0) / TIMELINE_MS * w;
    const posH = h * 0.5, velTop = posH + 6, velH = h * 0.32, bandTop = velTop + velH + 6, bandH = h - bandTop;
    let range = 5, vmax = 100;
    for (const p of samples) {
      if (p.t < t0 || !p.valid) continue;
      range = Math.max(range, Math.abs(p.xd), Math.abs(p.yd));
      vmax = Math.max(vmax, p.v);
    }
    vmax = Math.min(vmax, 1000);
    const Y = (deg) => posH / 2 - deg / range * (posH / 2 - 4);
    const V = (v) => velTop + velH - Math.min(v, vmax) / vmax * velH;
    g.strokeStyle = '#1f2937';
    g.beginPath(); g.moveTo(0, Y(0)); g.lineTo(w, Y(0)); g.stroke();
    // Label bands: one rectangle per run of one label.
    let runStart = null, runLabel = null;
    const closeRun = (end) => {
      if (runStart === null) return;
      g.fillStyle = COLOURS[runLabel];
      g.fillRect(X(runStart), bandTop, Math.max(1, X(end) - X(runStart)), bandH);
    };
    for (const p of samples) {
      if (p.t < t0 || p.label === runLabel) continue;
      closeRun(p.t);
      runStart = p.t;
      runLabel = p.label;
    }
    closeRun(t1);
    // A line through the samples, at most one point per pixel column (the column's last sample).
    const line = (value, colour, scale) => {
      g.strokeStyle = colour;
      g.beginPath();
      let open = false, column = -1;
      for (let k = 0; k < samples.length; k += 1) {
        const p = samples[k];
        if (p.t < t0 || !p.valid) { open = false; continue; }
        const x = X(p.t);
        const next = samples[k + 1];
        if (open && next && next.valid && Math.floor(X(next.t)) === Math.floor(x) && Math.floor(x) === column) continue;
        const y = scale(value(p));
        if (open) g.lineTo(x, y); else g.moveTo(x, y);
        open = true;
        column = Math.floor(x);
      }
      g.stroke();
    };
    line((p) => p.xd, '#f472b6', Y);
    line((p) => p.yd, '#a78bfa', Y);
    line((p) => p.v, '#e5e7eb', V);
    for (const m of marks) {
      if (m.t < t0) continue;
      g.strokeStyle = m.kind === 'marker' ? '#ffffff' : COLOURS[m.kind];
      g.setLineDash([2, 3]);
      g.beginPath(); g.moveTo(X(m.t), 0); g.lineTo(X(m.t), bandTop); g.stroke();
      g.setLineDash([]);
    }
    g.fillStyle = '#9ca3af';
    g.font = '11px system-ui, sans-serif';
    g.fillText(`x (pink), y (violet): ±${range.toFixed(0)}°`, 6, 12);
    g.fillText(`velocity 0..${vmax.toFixed(0)}°/s`, 6, velTop + 12);
    // Measured rate: samples in the last second of the stream.
    let n = 0;
    for (let k = samples.length - 1; k >= 0 && samples[k].t > t1 - 1000; k -= 1) n += 1;
    state.measured_rate_hz = n;
  }

  function row(tbody, name, value, bad) {
    const tr = document.createElement('tr');
    const a = document.createElement('td');
    const b = document.createElement('td');
    a.textContent = name;
    b.textContent = value;
    if (bad) b.className = 'bad';
    tr.append(a, b);
    tbody.append(tr);
  }

  const fmt = (v, digits = 1, unit = '') => (v === null || v === undefined ? '–' : `${Number(v).toFixed(digits)}${unit}`);

  function drawStatus() {
    const st = state.status, d = state.daemon;
    const tbody = $('status').tBodies[0];
    tbody.replaceChildren();
    const source = d.source || st.source;  // the daemon's own text is whole; STATUS_REPLY cuts it at 47 bytes
    $('source').textContent = source ? `${source} (${st.source_state || '–'})` : '';
    setBadge('connection', st.reachable === false ? 'off' : (state.connected ? 'on' : 'off'),
      st.reachable === false ? `daemon ${st.server} not answering` : (state.connected ? 'live' : 'disconnected'));
    row(tbody, 'Daemon', `${st.server || '–'}${st.subscribed ? ', subscribed' : ', not subscribed'}`, st.reachable === false);
    row(tbody, 'Source', `${source || '–'} (${st.source_state || '–'})${d.source_problem ? ': ' + d.source_problem : ''}`,
      st.source_state === 'retrying' || !!d.source_problem);
    row(tbody, 'Rate', `${fmt(state.measured_rate_hz, 0)} Hz received, nominal ${fmt(st.nominal_rate_hz, 0)} Hz`);
    row(tbody, 'Uptime', fmt(st.uptime_s, 0, ' s'));
    row(tbody, 'Published', `${st.samples_published ?? '–'} samples, ${st.events_published ?? '–'} events`);
    row(tbody, 'Subscribers', `${st.subscribers ?? '–'}`);
    row(tbody, 'Received here', `${st.received ?? '–'} samples, ${st.lost ?? '–'} lost, ${st.dropouts ?? '–'} dropouts (gaze became invalid)`, st.lost > 0);
    row(tbody, 'Clock', `offset ${fmt(st.clock_offset_ms, 3, ' ms')} (round trip ${fmt(st.clock_round_trip_ms, 3, ' ms')}), drift ${fmt(st.clock_drift_ppm, 1, ' ppm')}`);
    row(tbody, 'Latency', `to this monitor p50 ${fmt(st.latency_p50_ms, 2)} / p99 ${fmt(st.latency_p99_ms, 2)} ms; ` +
      `to this page drawn p50 ${fmt(state.latency.p50_ms, 1)} / p99 ${fmt(state.latency.p99_ms, 1)} ms`);
    row(tbody, 'Classifier', d.classifier || '–');
    const validation = d.calibration && d.calibration.validation;
    row(tbody, 'Calibration', d.calibration ? d.calibration.description : '–');
    row(tbody, 'Validated accuracy', validation && validation.accuracy_deg !== undefined && validation.accuracy_deg !== null
      ? `${fmt(validation.accuracy_deg, 2, '°')} on ${validation.targets ?? '?'} targets` : '–');
    row(tbody, 'Recording', d.recording || 'no');
    row(tbody, 'LSL outlet', d.lsl || 'none');
    row(tbody, 'Source counters', d.source_detail || '–');
    row(tbody, 'Viewer feed', st.viewer_feed || '–', st.viewer_feed && st.viewer_feed !== 'connected');
    row(tbody, 'Eye images', `${state.eye_frames} shown here; ${d.eye_frames_missed ?? 0} missed by slow viewers; ` +
      `latency p50 ${fmt(state.eye_latency.p50_ms, 1)} / p99 ${fmt(state.eye_latency.p99_ms, 1)} ms`);
  }

  function drawValidation() {
    const { g, s } = screenPanel('validation');
    const d = state.daemon;
    const v = d.calibration && d.calibration.validation;
    const points = v && Array.isArray(v.points) ? v.points : [];
    if (!d.calibration || d.calibration.description.startsWith('none')) { $('validation-info').textContent = 'no calibration loaded'; return; }
    if (points.length === 0) { $('validation-info').textContent = 'the calibration file has no per-target validation (made before fovea-calibrate recorded it)'; return; }
    const gain = 5;
    g.lineWidth = 2;
    for (const p of points) {
      const [tx, ty] = p.target_px;
      g.strokeStyle = '#e5e7eb';
      g.beginPath(); g.arc(tx * s, ty * s, 5, 0, 2 * Math.PI); g.stroke();
      if (!p.mean_error_px) continue;
      const [ex, ey] = p.mean_error_px;
      g.strokeStyle = '#f87171';
      g.beginPath(); g.moveTo(tx * s, ty * s); g.lineTo((tx + gain * ex) * s, (ty + gain * ey) * s); g.stroke();
    }
    $('validation-info').textContent = `${points.length} targets; mean error vectors drawn ${gain}× (accuracy ${fmt(v.accuracy_deg, 2, '°')})`;
  }

  function setBadge(id, cls, text) {
    const el = $(id);
    el.className = `badge ${cls}`;
    el.textContent = text;
  }

  function legend() {
    const el = $('legend');
    for (const name of LABELS) {
      const span = document.createElement('span');
      span.textContent = `● ${name}`;
      span.style.color = COLOURS[name];
      el.append(span);
    }
  }

  legend();
  connect();
  requestAnimationFrame(frame);
})();
