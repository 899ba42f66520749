// report.html's drawing: Figure 3 per initial configuration, the synchronised replay of the
// runs of one policy/configuration/repetition in every fidelity, the run list and the
// learning curves. Everything comes from the JSON in #cpmx-data; nothing is fetched.
"use strict";
(function () {
  const state = { errors: [], frame: 0, pair: 0, playing: false, speed: 1, timer: null };
  window.__cpmx = state;
  function recordError(message) {
    state.errors.push(String(message));
    document.body.dataset.errors = String(state.errors.length);
  }
  window.addEventListener("error", (e) => recordError(e.message));
  const consoleError = console.error.bind(console);
  console.error = (...args) => { recordError(args.join(" ")); consoleError(...args); };

  const data = JSON.parse(document.getElementById("cpmx-data").textContent);
  const COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                   "#7f7f7f", "#bcbd22", "#17becf"];
  const PANEL_W = 340, PANEL_H = 310, MARGIN = 12;

  // Map metres to canvas pixels: the whole map fits the panel, y up.
  function frameOf(canvas) {
    const [x0, y0, x1, y1] = data.map.bounds;
    const w = Math.max(x1 - x0, 1e-3), h = Math.max(y1 - y0, 1e-3);
    const scale = Math.min((canvas.width - 2 * MARGIN) / w, (canvas.height - 2 * MARGIN - 16) / h);
    return {
      scale,
      x: (xm) => MARGIN + (xm - x0) * scale,
      y: (ym) => MARGIN + (y1 - ym) * scale,
    };
  }
  function polyline(ctx, f, flat) {
    ctx.beginPath();
    for (let i = 0; i + 1 < flat.length; i += 2) {
      const px = f.x(flat[i]), py = f.y(flat[i + 1]);
      if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
    }
    ctx.stroke();
  }
  function roundLength(atMost) {
    const power = Math.pow(10, Math.floor(Math.log10(atMost)));
    for (const m of [5, 2, 1]) if (m * power <= atMost * (1 + 1e-9)) return m * power;
    return power;
  }
  function drawScaleBar(ctx, f, canvas) {
    const [x0, , x1] = data.map.bounds;
    const length = roundLength((x1 - x0) / 5);
    const px = length * f.scale, y = canvas.height - 8;
    ctx.strokeStyle = "#000"; ctx.lineWidth = 2; ctx.setLineDash([]);
    ctx.beginPath(); ctx.moveTo(MARGIN, y); ctx.lineTo(MARGIN + px, y); ctx.stroke();
    ctx.fillStyle = "#000"; ctx.font = "11px sans-serif";
    const label = length >= 1000 ? length / 1000 + " km" : length >= 1 ? length + " m" : Math.round(length * 100) + " cm";
    ctx.fillText(label, MARGIN + px + 5, y + 4);
  }
  function drawMap(ctx, f, canvas) {
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.strokeStyle = "#c8c8c8"; ctx.lineWidth = 1; ctx.setLineDash([]);
    for (const line of data.map.lanelets) polyline(ctx, f, line);
    drawScaleBar(ctx, f, canvas);
  }
  function footprint(ctx, f, x, y, yaw, colour, alpha) {
    const l = data.vehicle.length_m / 2, w = data.vehicle.width_m / 2;
    const c = Math.cos(yaw), s = Math.sin(yaw);
    const corners = [[l, w], [l, -w], [-l, -w], [-l, w]].map(([a, b]) => [x + a * c - b * s, y + a * s + b * c]);
    ctx.beginPath();
    corners.forEach(([cx, cy], i) => (i ? ctx.lineTo(f.x(cx), f.y(cy)) : ctx.moveTo(f.x(cx), f.y(cy))));
    ctx.closePath();
    ctx.globalAlpha = alpha; ctx.fillStyle = colour; ctx.fill();
    ctx.globalAlpha = 1; ctx.strokeStyle = "#000"; ctx.lineWidth = 1; ctx.setLineDash([]); ctx.stroke();
  }
  // One run at sample k: reference paths, trails, marks found by the metrics, footprints.
  function drawRun(canvas, run, k) {
    const ctx = canvas.getContext("2d"), f = frameOf(canvas);
    drawMap(ctx, f, canvas);
    run.ref_paths.forEach((id, agent) => {
      const path = data.map.paths[String(id)];
      if (!path) return;
      ctx.strokeStyle = COLOURS[agent % 10]; ctx.globalAlpha = 0.5; ctx.lineWidth = 1.5;
      ctx.setLineDash([6, 4]); polyline(ctx, f, path); ctx.globalAlpha = 1; ctx.setLineDash([]);
    });
    run.agents.forEach((a, agent) => {
      ctx.strokeStyle = COLOURS[agent % 10]; ctx.lineWidth = 1.5; ctx.beginPath();
      for (let i = 0; i <= Math.min(k, a.x.length - 1); i++) {
        if (a.x[i] === null) continue;
        if (i === 0) ctx.moveTo(f.x(a.x[i]), f.y(a.y[i])); else ctx.lineTo(f.x(a.x[i]), f.y(a.y[i]));
      }
      ctx.stroke();
    });
    for (const [agent, sample] of run.violations) {
      if (sample > k) continue;
      const a = run.agents[agent];
      ctx.fillStyle = "#ffa500"; ctx.beginPath();
      ctx.arc(f.x(a.x[sample]), f.y(a.y[sample]), 2.5, 0, 2 * Math.PI); ctx.fill();
    }
    for (const [sample, i, j] of run.collisions) {
      if (sample > k) continue;
      for (const agent of [i, j]) {
        const a = run.agents[agent];
        footprint(ctx, f, a.x[sample], a.y[sample], a.yaw[sample], "#ff0000", 0.45);
      }
    }
    run.agents.forEach((a, agent) => {
      const i = Math.min(k, a.x.length - 1);
      if (i >= 0 && a.x[i] !== null) footprint(ctx, f, a.x[i], a.y[i], a.yaw[i], COLOURS[agent % 10], 0.85);
    });
  }
  function panel(parent, caption) {
    const div = document.createElement("div");
    div.className = "panel";
    const canvas = document.createElement("canvas");
    canvas.width = PANEL_W; canvas.height = PANEL_H;
    div.appendChild(canvas);
    const text = document.createElement("div");
    text.className = "caption"; text.textContent = caption;
    div.appendChild(text);
    parent.appendChild(div);
    return { div, canvas, text };
  }
  const fmt = (v, d) => (v === null || v === undefined ? "n/a" : Number(v).toFixed(d));
  const samples = (run) => (run.agents.length ? run.agents[0].x.length : 0);

  // Figure 3.
  function drawFigure3() {
    const body = document.getElementById("figure3-body");
    for (const fig of data.figure3) {
      const block = document.createElement("div");
      block.className = "fig3";
      const title = document.createElement("h3");
      title.textContent = "initial configuration " + fig.configuration;
      block.appendChild(title);
      const row = document.createElement("div");
      row.className = "panels";
      block.appendChild(row);
      if (fig.setup !== null) {
        const run = data.runs[fig.setup];
        const p = panel(row, "setup: start poses and reference paths " + run.ref_paths.join(", "));
        drawRun(p.canvas, run, 0);
      }
      for (const rep of fig.representatives) {
        const run = data.runs[rep.run];
        const m = run.metrics;
        const p = panel(row, rep.group + ": " + run.key + " (policy " + run.policy + "; CD " + fmt(m.cd_m, 3) +
          " m, the group's mean " + fmt(rep.mean_cd_m, 3) + " m; CRA-A " + fmt(m.cra_a, 2) + ", AS " +
          fmt(m.as_mps, 3) + " m/s)");
        drawRun(p.canvas, run, samples(run) - 1);
      }
      body.appendChild(block);
    }
  }

  // The replay of one pair: its runs side by side on one clock.
  let panels = [];
  function showPair(index) {
    const pair = data.pairs[index];
    if (!pair) return;
    state.pair = index;
    const body = document.getElementById("replay-body");
    body.textContent = "";
    panels = pair.runs.map((r) => ({ run: data.runs[r], ...panel(body, data.runs[r].key) }));
    const length = Math.max(0, ...panels.map((p) => samples(p.run) - 1));
    const scrub = document.getElementById("scrub");
    scrub.max = String(length);
    document.getElementById("replay-title").textContent = pair.key;
    document.querySelectorAll("tr.run").forEach((tr) => tr.classList.toggle("selected", tr.dataset.pair === String(index)));
    setFrame(0);
  }
  function setFrame(k) {
    state.frame = k;
    document.getElementById("scrub").value = String(k);
    const dt = panels.length ? panels[0].run.dt : 0.1;
    document.getElementById("clock").textContent = "t = " + (k * dt).toFixed(1) + " s";
    for (const p of panels) {
      const i = Math.min(k, samples(p.run) - 1);
      drawRun(p.canvas, p.run, i);
      const speeds = p.run.agents.map((a, agent) => "agent " + agent + ": " + fmt(a.v[i], 2) + " m/s").join(" · ");
      p.text.textContent = p.run.key + " — " + speeds;
    }
    document.body.dataset.replayFrame = String(k);
  }
  function play(on) {
    state.playing = on;
    document.getElementById("play").textContent = on ? "Pause" : "Play";
    if (state.timer) clearInterval(state.timer);
    state.timer = null;
    if (!on || !panels.length) return;
    const dt = panels[0].run.dt, tick = 50;
    let carry = 0;
    state.timer = setInterval(() => {
      carry += (tick / 1000) * state.speed / dt;
      const steps = Math.floor(carry);
      carry -= steps;
      const last = Number(document.getElementById("scrub").max);
      if (steps > 0) setFrame(Math.min(last, state.frame + steps));
      if (state.frame >= last) play(false);
    }, tick);
  }

  // The run list: choosing a run opens its replay.
  function drawRunList() {
    const pairIndex = new Map(data.pairs.map((p, i) => [p.key, i]));
    const rows = data.runs.map((run) => {
      const m = run.metrics;
      return "<tr class=\"run\" data-pair=\"" + pairIndex.get(run.pair) + "\"><td>" + run.key + "</td><td class=\"num\">" +
        fmt(m.cra_a, 2) + "</td><td class=\"num\">" + fmt(m.cra_l, 2) + "</td><td class=\"num\">" + fmt(m.cd_m, 3) +
        "</td><td class=\"num\">" + fmt(m.as_mps, 3) + "</td><td class=\"num\">" + run.collisions.length + "</td></tr>";
    });
    document.getElementById("runs-body").innerHTML =
      "<table><thead><tr><th>run (click to replay)</th><th>CRA-A</th><th>CRA-L</th><th>CD [m]</th><th>AS [m/s]</th>" +
      "<th>collision events</th></tr></thead><tbody>" + rows.join("") + "</tbody></table>";
    document.querySelectorAll("tr.run").forEach((tr) => tr.addEventListener("click", () => {
      play(false);
      showPair(Number(tr.dataset.pair));
      document.getElementById("replay").scrollIntoView();
    }));
  }

  function drawLearningCurves() {
    const canvas = document.getElementById("learning-curves");
    if (!canvas || !data.learning_curves.length) return;
    const ctx = canvas.getContext("2d");
    const all = data.learning_curves.flatMap((c) => c.episode_reward_mean.filter((v) => v !== null));
    const iters = data.learning_curves.flatMap((c) => c.iteration);
    const [ymin, ymax] = [Math.min(...all), Math.max(...all)], xmax = Math.max(...iters, 1);
    const X = (i) => 50 + (i / xmax) * (canvas.width - 70), Y = (v) => canvas.height - 30 - ((v - ymin) / ((ymax - ymin) || 1)) * (canvas.height - 50);
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.fillStyle = "#000"; ctx.font = "11px sans-serif";
    ctx.fillText(ymax.toFixed(2), 4, Y(ymax) + 4); ctx.fillText(ymin.toFixed(2), 4, Y(ymin) + 4);
    ctx.fillText("iteration " + xmax, canvas.width - 90, canvas.height - 10);
    data.learning_curves.forEach((c, n) => {
      ctx.strokeStyle = COLOURS[n % 10]; ctx.beginPath();
      c.iteration.forEach((it, i) => (i ? ctx.lineTo(X(it), Y(c.episode_reward_mean[i])) : ctx.moveTo(X(it), Y(c.episode_reward_mean[i]))));
      ctx.stroke(); ctx.fillStyle = COLOURS[n % 10]; ctx.fillText(c.name, 60 + 90 * n, 14);
    });
  }

  // What a headless check reads back: how many pixels of the replay show vehicles' colours.
  function vehiclePixels() {
    if (!panels.length) return 0;
    const canvas = panels[0].canvas, pixels = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
    let count = 0;
    for (let i = 0; i < pixels.length; i += 4) {
      const [r, g, b] = [pixels[i], pixels[i + 1], pixels[i + 2]];
      if (Math.max(r, g, b) - Math.min(r, g, b) > 60) count++;
    }
    return count;
  }

  document.getElementById("play").addEventListener("click", () => play(!state.playing));
  document.getElementById("scrub").addEventListener("input", (e) => { play(false); setFrame(Number(e.target.value)); });
  document.getElementById("speed").addEventListener("change", (e) => { state.speed = Number(e.target.value); });
  drawFigure3();
  drawRunList();
  drawLearningCurves();
  showPair(0);
  document.body.dataset.vehiclePixels = String(vehiclePixels());
  document.body.dataset.ready = "1";
  if (location.hash === "#autoplay") {
    state.speed = 8;
    play(true);
  }
})();
