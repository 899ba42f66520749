// report.html's drawing: Figure 3 per initial configuration, the synchronised replay of the
// runs of one policy/configuration/repetition in every fidelity, the run list and the
// learning curves, each canvas as wide as the page's grid gives it and at the screen's
// resolution. Everything comes from the JSON in #cpmx-data; nothing is fetched.
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
  // Agents take Okabe–Ito's colour-blind-safe colours (as cpmx-env's render.rs does); events
  // are drawn in inks no agent takes, and so that they hide no trajectory: a lane-violation
  // episode as a translucent grey band under the trajectory with a hollow ring where it
  // starts, a collision as the two vehicles' outlines and a black cross between them.
  const COLOURS = ["#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442"];
  const colour = (i) => COLOURS[i % COLOURS.length];
  const COLLISION_INK = "#000000", VIOLATION_INK = "#404040";
  // Canvas layout in CSS pixels: a border, and room for the scale bar at the bottom.
  const MARGIN = 12, SCALE_BAR = 22;
  // Map panels keep their map's aspect ratio (within reason), whatever width the page gives them.
  // A run drives on one of the page's maps (data.maps[run.map]): the spec's, or its
  // configuration's own.
  const mapOf = (run) => data.maps[run.map];
  function mapAspect(map) {
    const [x0, y0, x1, y1] = map.bounds, w = 440;
    const h = (w - 2 * MARGIN) * Math.max(y1 - y0, 1e-3) / Math.max(x1 - x0, 1e-3) + 2 * MARGIN + SCALE_BAR;
    return Math.min(3, Math.max(0.6, w / h));
  }

  // Canvases are drawn at the screen's resolution: the backing store is the CSS size times
  // devicePixelRatio, and every drawing works in CSS pixels. Each canvas keeps the function
  // that draws it, called again when its size or the resolution changes.
  const redraws = new Map();
  const sharp = (canvas) => {
    const ratio = window.devicePixelRatio || 1;
    return canvas.width === Math.round(canvas.clientWidth * ratio) && canvas.height === Math.round(canvas.clientHeight * ratio);
  };
  const observer = typeof ResizeObserver === "function"
    ? new ResizeObserver((entries) => {
      for (const e of entries) if (!sharp(e.target)) redraws.get(e.target)?.();
      measureLayout();
    })
    : null;
  function register(canvas, draw) {
    redraws.set(canvas, draw);
    if (observer) observer.observe(canvas);
    draw();
  }
  function unregister(canvas) {
    redraws.delete(canvas);
    if (observer) observer.unobserve(canvas);
  }
  let resolution = window.devicePixelRatio || 1;
  window.addEventListener("resize", () => {
    if ((window.devicePixelRatio || 1) !== resolution) {
      resolution = window.devicePixelRatio || 1;
      redraws.forEach((draw) => draw());
    }
    measureLayout();
  });
  function fit(canvas) {
    const ratio = window.devicePixelRatio || 1;
    const w = canvas.clientWidth || 400, h = canvas.clientHeight || 300;
    const W = Math.round(w * ratio), H = Math.round(h * ratio);
    if (canvas.width !== W || canvas.height !== H) { canvas.width = W; canvas.height = H; }
    const ctx = canvas.getContext("2d");
    ctx.setTransform(W / w, 0, 0, H / h, 0, 0);
    return { ctx, w, h };
  }

  // Map metres to CSS pixels: the whole map fits the panel, centred, y up.
  function frameOf(w, h, map) {
    const [x0, y0, x1, y1] = map.bounds;
    const mw = Math.max(x1 - x0, 1e-3), mh = Math.max(y1 - y0, 1e-3);
    const scale = Math.max(1e-9, Math.min((w - 2 * MARGIN) / mw, (h - 2 * MARGIN - SCALE_BAR) / mh));
    const left = MARGIN + Math.max(0, (w - 2 * MARGIN - mw * scale) / 2);
    return {
      scale,
      x: (xm) => left + (xm - x0) * scale,
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
  function drawScaleBar(ctx, f, h, map) {
    const [x0, , x1] = map.bounds;
    const length = roundLength((x1 - x0) / 5);
    const px = length * f.scale, y = h - 10, x = f.x(x0);
    ctx.strokeStyle = "#000"; ctx.lineWidth = 2; ctx.setLineDash([]);
    ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(x + px, y); ctx.stroke();
    ctx.fillStyle = "#000"; ctx.font = "11px sans-serif";
    const label = length >= 1000 ? length / 1000 + " km" : length >= 1 ? length + " m" : Math.round(length * 100) + " cm";
    ctx.fillText(label, x + px + 5, y + 4);
  }
  function drawMap(ctx, f, w, h, map) {
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, w, h);
    ctx.strokeStyle = "#c8c8c8"; ctx.lineWidth = 1; ctx.setLineDash([]);
    for (const line of map.lanelets) polyline(ctx, f, line);
    drawScaleBar(ctx, f, h, map);
  }
  function corners(x, y, yaw) {
    const l = data.vehicle.length_m / 2, w = data.vehicle.width_m / 2;
    const c = Math.cos(yaw), s = Math.sin(yaw);
    return [[l, w], [l, -w], [-l, -w], [-l, w]].map(([a, b]) => [x + a * c - b * s, y + a * s + b * c]);
  }
  function outlinePath(ctx, f, x, y, yaw) {
    ctx.beginPath();
    corners(x, y, yaw).forEach(([cx, cy], i) => (i ? ctx.lineTo(f.x(cx), f.y(cy)) : ctx.moveTo(f.x(cx), f.y(cy))));
    ctx.closePath();
  }
  function footprint(ctx, f, x, y, yaw, fill) {
    outlinePath(ctx, f, x, y, yaw);
    ctx.globalAlpha = 0.85; ctx.fillStyle = fill; ctx.fill();
    ctx.globalAlpha = 1; ctx.strokeStyle = "#000"; ctx.lineWidth = 1; ctx.setLineDash([]); ctx.stroke();
  }
  function cross(ctx, x, y, half) {
    ctx.beginPath();
    ctx.moveTo(x - half, y - half); ctx.lineTo(x + half, y + half);
    ctx.moveTo(x - half, y + half); ctx.lineTo(x + half, y - half);
    ctx.stroke();
  }
  // A run's lane-violation episodes (consecutive samples of one agent): [agent, first, last].
  function episodes(run) {
    if (!run.episodes) {
      run.episodes = [];
      for (const [agent, sample] of run.violations) {
        const last = run.episodes[run.episodes.length - 1];
        if (last && last[0] === agent && last[2] + 1 === sample) last[2] = sample;
        else run.episodes.push([agent, sample, sample]);
      }
    }
    return run.episodes;
  }
  // Agent a's `field` at drawn sample i: its arrays start at its first drawn sample (agents
  // placed later under `on_collision: replace-agent` start later, and leave earlier).
  const at = (a, field, i) => a[field][i - a.first];
  const defined = (a, i) => {
    const j = i - a.first;
    return j >= 0 && j < a.x.length && a.x[j] !== null && a.y[j] !== null;
  };
  // One run at sample k: violation bands, reference paths, trails, collision marks, violation
  // rings, footprints.
  function drawRun(canvas, run, k) {
    const map = mapOf(run);
    const { ctx, w, h } = fit(canvas), f = frameOf(w, h, map);
    drawMap(ctx, f, w, h, map);
    ctx.lineCap = "round"; ctx.lineJoin = "round";
    for (const [agent, first, last] of episodes(run)) {
      const a = run.agents[agent];
      if (first > k || !a) continue;
      ctx.strokeStyle = VIOLATION_INK; ctx.fillStyle = VIOLATION_INK; ctx.globalAlpha = 0.25; ctx.lineWidth = 7;
      ctx.beginPath();
      let points = 0;
      for (let i = first; i <= Math.min(last, k); i++) {
        if (!defined(a, i)) continue;
        if (points++ === 0) ctx.moveTo(f.x(at(a, "x", i)), f.y(at(a, "y", i))); else ctx.lineTo(f.x(at(a, "x", i)), f.y(at(a, "y", i)));
      }
      if (points > 1) ctx.stroke();
      else if (points === 1 && defined(a, first)) {
        ctx.beginPath(); ctx.arc(f.x(at(a, "x", first)), f.y(at(a, "y", first)), 3.5, 0, 2 * Math.PI); ctx.fill();
      }
      ctx.globalAlpha = 1;
    }
    ctx.lineCap = "butt"; ctx.lineJoin = "miter";
    run.ref_paths.forEach((id, agent) => {
      const path = map.paths[String(id)];
      if (!path) return;
      ctx.strokeStyle = colour(agent); ctx.globalAlpha = 0.5; ctx.lineWidth = 1.5;
      ctx.setLineDash([6, 4]); polyline(ctx, f, path); ctx.globalAlpha = 1; ctx.setLineDash([]);
    });
    run.agents.forEach((a, agent) => {
      ctx.strokeStyle = colour(agent); ctx.lineWidth = 1.5; ctx.beginPath();
      let started = false;
      for (let i = a.first; i <= Math.min(k, a.first + a.x.length - 1); i++) {
        if (!defined(a, i)) continue;
        if (!started) ctx.moveTo(f.x(at(a, "x", i)), f.y(at(a, "y", i))); else ctx.lineTo(f.x(at(a, "x", i)), f.y(at(a, "y", i)));
        started = true;
      }
      ctx.stroke();
    });
    ctx.strokeStyle = COLLISION_INK; ctx.setLineDash([]);
    for (const [sample, i, j] of run.collisions) {
      const [a, b] = [run.agents[i], run.agents[j]];
      if (sample > k || !a || !b || !defined(a, sample) || !defined(b, sample)) continue;
      ctx.lineWidth = 1.5;
      for (const v of [a, b]) { outlinePath(ctx, f, at(v, "x", sample), at(v, "y", sample), at(v, "yaw", sample)); ctx.stroke(); }
      ctx.lineWidth = 2.5;
      cross(ctx, (f.x(at(a, "x", sample)) + f.x(at(b, "x", sample))) / 2, (f.y(at(a, "y", sample)) + f.y(at(b, "y", sample))) / 2, 5);
    }
    ctx.strokeStyle = VIOLATION_INK; ctx.lineWidth = 1.5;
    for (const [agent, first] of episodes(run)) {
      const a = run.agents[agent];
      if (first > k || !a || !defined(a, first)) continue;
      ctx.beginPath(); ctx.arc(f.x(at(a, "x", first)), f.y(at(a, "y", first)), 5, 0, 2 * Math.PI); ctx.stroke();
    }
    run.agents.forEach((a, agent) => {
      const i = k;
      if (defined(a, i)) footprint(ctx, f, at(a, "x", i), at(a, "y", i), at(a, "yaw", i), colour(agent));
    });
  }
  // A figure of the page: a canvas showing `run` on its map, and a caption.
  function panel(parent, caption, run) {
    const figure = document.createElement("figure");
    figure.className = "panel";
    const canvas = document.createElement("canvas");
    canvas.style.aspectRatio = String(mapAspect(mapOf(run)));
    figure.appendChild(canvas);
    const text = document.createElement("figcaption");
    text.textContent = caption;
    figure.appendChild(text);
    parent.appendChild(figure);
    return { figure, canvas, text };
  }
  // What the marks mean, with each agent's colour.
  function legend(id) {
    const box = document.getElementById(id);
    if (!box) return;
    // One entry per colour at most: agents beyond them repeat the colours.
    const agents = Math.min(COLOURS.length, Math.max(0, ...data.runs.map((r) => r.agents.length)));
    const icon = (body) => "<svg width=\"22\" height=\"14\" viewBox=\"0 0 22 14\" aria-hidden=\"true\">" + body + "</svg>";
    const items = [];
    for (let agent = 0; agent < agents; agent++) {
      items.push(icon("<path d=\"M1 7 L21 7\" stroke=\"" + colour(agent) + "\" stroke-width=\"3\"/>") + "agent " + agent);
    }
    items.push(icon("<path d=\"M1 7 L21 7\" stroke=\"#888\" stroke-width=\"1.5\" stroke-dasharray=\"6 4\"/>") +
      "reference path (dashed, the agent's colour)");
    items.push(icon("<path d=\"M4 7 L18 7\" stroke=\"" + VIOLATION_INK + "\" stroke-opacity=\"0.25\" stroke-width=\"7\" " +
      "stroke-linecap=\"round\"/><circle cx=\"5\" cy=\"7\" r=\"5\" fill=\"none\" stroke=\"" + VIOLATION_INK + "\" stroke-width=\"1.5\"/>") +
      "lane violation: grey band under the stretch out of lane, ring where it starts");
    items.push(icon("<path d=\"M6 2 L16 12 M6 12 L16 2\" stroke=\"" + COLLISION_INK + "\" stroke-width=\"2.5\"/>") +
      "collision event: cross, both vehicles outlined");
    items.push(icon("<rect x=\"4\" y=\"3\" width=\"14\" height=\"8\" fill=\"" + colour(0) + "\" fill-opacity=\"0.85\" stroke=\"#000\"/>") +
      "vehicle (filled: where it is at the time shown)");
    box.innerHTML = items.map((item) => "<span>" + item + "</span>").join("");
  }
  const fmt = (v, d) => (v === null || v === undefined ? "n/a" : Number(v).toFixed(d));
  const samples = (run) => run.samples;

  // Who ran: fidelity, policy, initial configuration and repetition, as captions name them.
  const describe = (run) => "fidelity " + run.fidelity + " · policy " + run.policy + " · " + run.configuration +
    " · repetition " + run.repetition;
  const list = (values) => values.join(", ");

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
      body.appendChild(block);
      if (fig.setup !== null) {
        const run = data.runs[fig.setup];
        const p = panel(row, "Setup of " + fig.configuration + ": start poses and reference paths " + list(run.ref_paths) +
          " (the same for every fidelity and for " + (fig.policies.length > 1 ? "the policies " : "the policy ") +
          list(fig.policies) + ")", run);
        register(p.canvas, () => drawRun(p.canvas, run, 0));
      }
      for (const rep of fig.representatives) {
        const run = data.runs[rep.run];
        const m = run.metrics;
        let caption = "Policy " + run.policy + ", fidelity " + run.fidelity + " (run " + run.key + "): CD " + fmt(m.cd_m, 3) +
          " m, its summary row's mean " + fmt(rep.mean_cd_m, 3) + " m; CRA-A " + fmt(m.cra_a, 2) + ", AS " +
          fmt(m.as_mps, 3) + " m/s";
        if (rep.group_policies.length > 1) {
          caption += ". The row " + rep.group + " pools the policies " + list(rep.group_policies) +
            "; this run is the one closest to its mean";
        }
        const p = panel(row, caption, run);
        register(p.canvas, () => drawRun(p.canvas, run, samples(run) - 1));
      }
    }
  }

  // The replay of one pair: its runs side by side on one clock.
  let panels = [];
  function showPair(index) {
    const pair = data.pairs[index];
    if (!pair) return;
    state.pair = index;
    const body = document.getElementById("replay-body");
    for (const p of panels) unregister(p.canvas);
    body.textContent = "";
    panels = pair.runs.map((r) => ({ run: data.runs[r], ...panel(body, describe(data.runs[r]), data.runs[r]) }));
    const length = Math.max(0, ...panels.map((p) => samples(p.run) - 1));
    const scrub = document.getElementById("scrub");
    scrub.max = String(length);
    const first = panels.length ? panels[0].run : null;
    document.getElementById("replay-title").textContent = first
      ? "policy " + first.policy + " · " + first.configuration + " · repetition " + first.repetition
      : pair.key;
    document.querySelectorAll("tr.run").forEach((tr) => tr.classList.toggle("selected", tr.dataset.pair === String(index)));
    setFrame(0);
    for (const p of panels) register(p.canvas, () => drawPanel(p, state.frame));
  }
  function drawPanel(p, k) {
    const i = Math.min(k, samples(p.run) - 1);
    drawRun(p.canvas, p.run, i);
    const speeds = p.run.agents
      .map((a, agent) => (defined(a, i) ? "agent " + agent + " " + fmt(at(a, "v", i), 2) + " m/s" : null))
      .filter((text) => text !== null)
      .join(", ");
    p.text.textContent = describe(p.run) + " — " + speeds;
  }
  function setFrame(k) {
    state.frame = k;
    document.getElementById("scrub").value = String(k);
    const dt = panels.length ? panels[0].run.dt : 0.1;
    document.getElementById("clock").textContent = "t = " + (k * dt).toFixed(1) + " s";
    for (const p of panels) drawPanel(p, k);
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
      "<div class=\"table-wrap\"><table><thead><tr><th>run (click to replay)</th><th>CRA-A</th><th>CRA-L</th><th>CD [m]</th><th>AS [m/s]</th>" +
      "<th>collision events</th></tr></thead><tbody>" + rows.join("") + "</tbody></table></div>";
    document.querySelectorAll("tr.run").forEach((tr) => tr.addEventListener("click", () => {
      play(false);
      showPair(Number(tr.dataset.pair));
      document.getElementById("replay").scrollIntoView();
    }));
  }

  // A value axis: the values' range padded by 5 %; a constant from zero to it ([0, 1] for
  // zero or no value), as the distribution plots do.
  function axisRange(values) {
    let [low, high] = [Math.min(...values), Math.max(...values)];
    if (!(low <= high)) [low, high] = [0, 1];
    else if (low === high) [low, high] = low === 0 ? [0, 1] : [Math.min(0, low), Math.max(0, low)];
    const pad = 0.05 * (high - low);
    return [low - pad, high + pad];
  }
  function niceStep(raw) {
    const power = Math.pow(10, Math.floor(Math.log10(raw)));
    for (const m of [1, 2, 5, 10]) if (m * power >= raw) return m * power;
    return 10 * power;
  }
  function drawLearningCurves(canvas) {
    const { ctx, w, h } = fit(canvas);
    const all = data.learning_curves.flatMap((c) => c.episode_reward_mean.filter((v) => v !== null));
    const iters = data.learning_curves.flatMap((c) => c.iteration);
    const [ymin, ymax] = axisRange(all), xmax = Math.max(...iters, 1);
    const [left, right, top, bottom] = [64, 16, 28, 34];
    const X = (i) => left + (i / xmax) * (w - left - right);
    const Y = (v) => top + ((ymax - v) / (ymax - ymin)) * (h - top - bottom);
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, w, h);
    ctx.font = "11px sans-serif"; ctx.lineWidth = 1;
    const step = niceStep((ymax - ymin) / 5), decimals = Math.max(0, -Math.floor(Math.log10(step)));
    for (let v = Math.ceil(ymin / step) * step; v <= ymax; v += step) {
      ctx.strokeStyle = "#e0e0e0"; ctx.beginPath(); ctx.moveTo(left, Y(v)); ctx.lineTo(w - right, Y(v)); ctx.stroke();
      ctx.fillStyle = "#000"; ctx.textAlign = "right"; ctx.fillText(v.toFixed(decimals), left - 6, Y(v) + 4);
    }
    ctx.strokeStyle = "#000"; ctx.beginPath(); ctx.moveTo(left, top); ctx.lineTo(left, h - bottom);
    ctx.lineTo(w - right, h - bottom); ctx.stroke();
    ctx.textAlign = "right"; ctx.fillText("iteration " + xmax, w - right, h - 10);
    ctx.textAlign = "left"; ctx.fillText("0", left, h - 10);
    let x = left;
    data.learning_curves.forEach((c, n) => {
      ctx.strokeStyle = colour(n); ctx.lineWidth = 1.5; ctx.beginPath();
      let started = false;
      c.iteration.forEach((it, i) => {
        const v = c.episode_reward_mean[i];
        if (v === null) return;
        if (started) ctx.lineTo(X(it), Y(v)); else ctx.moveTo(X(it), Y(v));
        started = true;
      });
      ctx.stroke();
      ctx.fillStyle = colour(n); ctx.fillRect(x, 9, 14, 4);
      ctx.fillStyle = "#000"; ctx.fillText(c.name, x + 18, 14);
      x += 30 + ctx.measureText(c.name).width;
    });
  }
  function drawTraining() {
    const canvas = document.getElementById("learning-curves");
    if (!canvas || !data.learning_curves.length) return;
    register(canvas, () => drawLearningCurves(canvas));
  }

  // What a headless check reads back about the layout: the viewport's width, how far the page
  // overflows it sideways, the canvases' resolution (backing-store pixels per CSS pixel, the
  // least of them) and every figure as "section left top width drawing-width" (CSS pixels;
  // the drawing is the figure's canvas or SVG).
  function measureLayout() {
    const root = document.documentElement;
    document.body.dataset.viewportWidth = String(root.clientWidth);
    document.body.dataset.overflowX = String(Math.max(0, root.scrollWidth - root.clientWidth));
    // How far the widest table reaches past its box (scrolled sideways to be read), and the
    // smallest text of any figure's SVG as drawn (its font size times the drawing's scale).
    const tables = [...document.querySelectorAll(".table-wrap")].map((w) => w.scrollWidth - w.clientWidth);
    document.body.dataset.tableOverflowX = String(Math.max(0, ...tables));
    const sizes = [...document.querySelectorAll("figure svg")].flatMap((svg) => {
      const natural = svg.viewBox.baseVal && svg.viewBox.baseVal.width ? svg.viewBox.baseVal.width
        : parseFloat(svg.getAttribute("width") || "0");
      const drawn = svg.getBoundingClientRect().width;
      if (!natural || !drawn) return [];
      return [...svg.querySelectorAll("text")].map((t) => parseFloat(getComputedStyle(t).fontSize) * drawn / natural);
    });
    document.body.dataset.smallestFigureTextPx = sizes.length ? Math.min(...sizes).toFixed(1) : "0";
    const scales = [...redraws.keys()].filter((c) => c.clientWidth > 0).map((c) => c.width / c.clientWidth);
    document.body.dataset.canvasScale = scales.length ? Math.min(...scales).toFixed(2) : "0";
    document.body.dataset.figures = [...document.querySelectorAll("figure")].map((figure) => {
      const r = figure.getBoundingClientRect(), section = figure.closest("section");
      const drawing = figure.querySelector("canvas, svg");
      const drawn = drawing ? drawing.getBoundingClientRect().width : 0;
      return [section ? section.id : "", Math.round(r.left), Math.round(r.top + window.scrollY), Math.round(r.width),
        Math.round(drawn)].join(" ");
    }).join(";");
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
  legend("figure3-legend");
  legend("replay-legend");
  drawFigure3();
  drawRunList();
  drawTraining();
  showPair(0);
  measureLayout();
  document.body.dataset.vehiclePixels = String(vehiclePixels());
  document.body.dataset.ready = "1";
  if (location.hash === "#autoplay") {
    state.speed = 8;
    play(true);
  }
})();
