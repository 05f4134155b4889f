// The report's plots, drawn with uPlot from the data block (sniffer/report/page.py writes both inline).
// Every plot over time zooms (drag, wheel) and pans (Shift+drag, middle button); double-click shows all.
// window.__report.plots lists each plot: its id, how many data points it has and how many series it drew
// (tests/test_report_chromium.py reads it).
(function () {
  "use strict";
  const D = JSON.parse(document.getElementById("report-data").textContent);
  const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2",
                  "#7f7f7f", "#bcbd22"];
  const plots = [];
  window.__report = {plots: plots, errors: []};
  const clock = D.axis.clock, origin = D.axis.origin_wall_s;
  const X = (t) => (clock ? origin + t : t);
  let syncing = true;  // no zoom is shared while the plots are built (each sets its own range)
  const syncBox = document.getElementById("sync");

  function color(i) { return COLORS[i % COLORS.length]; }
  function alpha(c, a) { return c + Math.round(a * 255).toString(16).padStart(2, "0"); }
  function widthOf(el) { return Math.max(360, Math.floor(el.getBoundingClientRect().width) || 900); }

  function clockText(v) {
    const s = Math.round(v), h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
    return (h ? h + ":" + String(m).padStart(2, "0") : String(m)) + ":" + String(sec).padStart(2, "0");
  }
  function relValues(u, splits) {
    const span = u.scales.x.max - u.scales.x.min;
    return splits.map((v) => (span >= 300 ? clockText(v) : +v.toFixed(span < 1 ? 4 : 2) + " s"));
  }
  function timeXAxis() { return clock ? {} : {values: relValues}; }

  // aligned data for uPlot from series of {t, v} with their own times
  function union(series) {
    const all = [0, D.axis.end_s];  // every plot over time spans the report: the same view in all of them
    series.forEach((s) => { for (const t of s.t) all.push(t); });
    all.sort((a, b) => a - b);
    const xs = [];
    for (const t of all) if (!xs.length || xs[xs.length - 1] !== t) xs.push(t);
    const at = new Map(xs.map((t, i) => [t, i]));
    const data = [xs.map(X)];
    series.forEach((s) => {
      const ys = new Array(xs.length).fill(null);
      s.t.forEach((t, i) => { ys[at.get(t)] = s.v[i]; });
      data.push(ys);
    });
    return data;
  }

  function zoomPan() {
    return {hooks: {ready: (u) => {
      const over = u.over;
      const full = () => { const xs = u.data[0]; return [xs[0], xs[xs.length - 1]]; };
      over.addEventListener("wheel", (e) => {
        e.preventDefault();
        const s = u.scales.x, rect = over.getBoundingClientRect();
        const at = u.posToVal(e.clientX - rect.left, "x");
        const f = e.deltaY < 0 ? 0.75 : 1 / 0.75;
        let min = at - (at - s.min) * f, max = at + (s.max - at) * f;
        const [lo, hi] = full();
        if (max - min >= hi - lo) { min = lo; max = hi; }
        u.setScale("x", {min: min, max: max});
      }, {passive: false});
      // before uPlot's own drag-to-zoom (on u.over): the capture phase of its parent
      u.root.addEventListener("mousedown", (e) => {
        if (!(e.shiftKey || e.button === 1) || !over.contains(e.target)) return;
        e.preventDefault();
        e.stopPropagation();
        const x0 = e.clientX, min0 = u.scales.x.min, max0 = u.scales.x.max, w = over.clientWidth;
        const move = (ev) => {
          const dx = (ev.clientX - x0) * (max0 - min0) / w;
          u.setScale("x", {min: min0 - dx, max: max0 - dx});
        };
        const up = () => { document.removeEventListener("mousemove", move); document.removeEventListener("mouseup", up); };
        document.addEventListener("mousemove", move);
        document.addEventListener("mouseup", up);
      }, true);
    }}};
  }

  function make(id, opts, data, kind) {
    const el = document.getElementById(id);
    if (!el) return null;
    let points = 0;
    for (let i = 1; i < data.length; i++) for (const y of data[i]) if (y !== null && y !== undefined) points++;
    const rec = {id: id, kind: kind, points: points, drawn: 0, colors: [], u: null};
    opts.width = widthOf(el);
    opts.height = opts.height || 260;
    opts.hooks = opts.hooks || {};
    (opts.hooks.drawSeries = opts.hooks.drawSeries || []).push(() => { rec.drawn++; });
    opts.series.slice(1).forEach((s) => { if (s.stroke) rec.colors.push(s.stroke); });
    if (kind === "time") {
      opts.plugins = (opts.plugins || []).concat([zoomPan()]);
      opts.cursor = Object.assign({sync: {key: "t"}, drag: {x: true, y: false}}, opts.cursor || {});
      (opts.hooks.setScale = opts.hooks.setScale || []).push((u, key) => {
        if (key !== "x" || syncing || !syncBox || !syncBox.checked) return;
        syncing = true;
        try {
          for (const p of plots) {
            if (p.u !== u && p.kind === "time") p.u.setScale("x", {min: u.scales.x.min, max: u.scales.x.max});
          }
        } finally { syncing = false; }
      });
    }
    const u = new uPlot(opts, data, el);
    rec.u = u;
    plots.push(rec);
    return rec;
  }

  function timeOpts(series, yLabel, extra) {
    return Object.assign({
      scales: {x: {time: clock}},
      axes: [timeXAxis(), {label: yLabel, size: 60}],
      series: [{label: clock ? "time" : "s"}].concat(series),
    }, extra || {});
  }

  const stepped = uPlot.paths.stepped({align: 1});
  const noPath = () => null;

  // ---------------------------------------------------------------- latency
  function latency() {
    const L = D.latency, units = Object.keys(L.bins);
    if (!units.length) return;
    let first = L.edges.length, last = -1;
    units.forEach((u) => L.bins[u].forEach((n, i) => { if (n) { first = Math.min(first, i); last = Math.max(last, i); } }));
    first = Math.max(0, first - 1);
    last = Math.min(L.bins[units[0]].length - 1, last + 1);
    const xs = L.edges.slice(first, last + 2);
    const data = [xs].concat(units.map((u) => L.bins[u].slice(first, last + 1).concat([0])));
    make("plot-lat-hist", {
      scales: {x: {time: false, distr: 3}},
      axes: [{label: "ms", values: (u, v) => v.map((x) => (x == null ? "" : +x.toPrecision(3)))}, {label: "responses", size: 60}],
      series: [{label: "ms"}].concat(units.map((u, i) => ({label: "unit " + u, stroke: color(i),
        fill: alpha(color(i), 0.12), paths: stepped, width: 1.5, points: {show: false}}))),
    }, data, "hist");
    const series = units.map((u) => L.series[u]);
    make("plot-lat-time", timeOpts(units.map((u, i) => ({label: "unit " + u, stroke: color(i), paths: noPath,
      points: {show: true, size: 4, fill: color(i), stroke: color(i)}})), "ms"), union(series), "time");
  }

  // ---------------------------------------------------------------- polls
  function polls() {
    const S = D.polls.series;
    if (!S.length) return;
    make("plot-polls", timeOpts(S.map((s, i) => ({label: s.label, stroke: color(i), paths: noPath,
      points: {show: true, size: 4, fill: color(i)}})), "ms between polls", {height: 300}), union(S), "time");
  }

  // ---------------------------------------------------------------- buckets
  function buckets() {
    const B = D.buckets, n = B.x.length;
    if (!n) return;
    const xs = B.x.map(X).concat([X(Math.max(B.x[n - 1], Math.min(B.x[n - 1] + B.width_s, D.axis.end_s)))]);
    const end = (arr) => arr.concat([arr.length ? arr[arr.length - 1] : 0]);
    const util = B.busy_ns.map((b, i) => (B.span_s[i] > 0 ? Math.min(100, b / 1e9 / B.span_s[i] * 100) : null));
    const fps = B.frames.map((f, i) => (B.span_s[i] > 0 ? f / B.span_s[i] : null));
    make("plot-util", timeOpts([
      {label: "busy %", stroke: color(0), fill: alpha(color(0), 0.15), paths: stepped, scale: "%"},
      {label: "frames/s", stroke: color(1), paths: stepped, scale: "fps"},
    ], "% busy", {scales: {x: {time: clock}, "%": {range: [0, 100]}},
      axes: [timeXAxis(), {scale: "%", label: "% busy", size: 60}, {scale: "fps", side: 1, label: "frames/s", size: 60,
        grid: {show: false}}]}), [xs, end(util), end(fps)], "time");
    const kinds = [["crc", "CRC errors"], ["exceptions", "exceptions"], ["timeouts", "timeouts (no response)"],
                   ["retries", "retries"], ["noise", "noise"], ["gaps", "capture gaps"]];
    const shown = kinds.filter(([k], i) => i < 4 || B[k].some((v) => v));
    make("plot-errors", timeOpts(shown.map(([k, label], i) => ({label: label, stroke: color(i + 1), paths: stepped,
      width: 1.5})), "per bucket"), [xs].concat(shown.map(([k]) => end(B[k]))), "time");
    const v = [["fast35", "responses under t3.5"], ["fast15", "responses under t1.5"],
               ["t35", "frames flagged t3.5 (started early)"], ["t15", "frames flagged t1.5 (gap inside)"]];
    make("plot-violations", timeOpts(v.map(([k, label], i) => ({label: label, stroke: color(i + 4), paths: stepped,
      width: 1.5})), "per bucket", {height: 220}), [xs].concat(v.map(([k]) => end(B[k]))), "time");
  }

  // ---------------------------------------------------------------- turnaround
  function turnaround() {
    const T = D.turnaround, units = Object.keys(T.bins);
    if (!units.length) return;
    const step = T.edges[1] - T.edges[0];
    let last = 0;  // the bins shown: up to the last one used, and past the line's t3.5
    units.forEach((u) => T.bins[u].forEach((n, i) => { if (n) last = Math.max(last, i); }));
    for (const [, b] of T.limits) last = Math.max(last, Math.ceil(b / step) + 4);
    last = Math.min(last + 1, T.edges.length - 1);
    const xs = T.edges.slice(0, last + 1).concat([T.edges[last] + step]);
    const data = [xs].concat(units.map((u) => T.bins[u].slice(0, last + 1).concat([0])));
    const marks = (u) => {
      const ctx = u.ctx;
      ctx.save();
      ctx.setLineDash([6, 4]);
      ctx.strokeStyle = "#b3261e";
      ctx.fillStyle = "#b3261e";
      ctx.font = Math.round(11 * devicePixelRatio) + "px sans-serif";
      const seen = new Set(), lines = [];
      for (const [a, b] of T.limits) {
        for (const [v, label] of [[a, "t1.5"], [b, "t3.5"]]) {
          if (!seen.has(v)) { seen.add(v); lines.push([v, label]); }
        }
      }
      for (const [v, label] of lines) {
        const x = u.valToPos(v, "x", true);
        if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) continue;
        ctx.beginPath();
        ctx.moveTo(x, u.bbox.top);
        ctx.lineTo(x, u.bbox.top + u.bbox.height);
        ctx.stroke();
        ctx.fillText(label, x + 4, u.bbox.top + 14 * devicePixelRatio);
      }
      ctx.restore();
    };
    make("plot-turn", {
      scales: {x: {time: false}},
      axes: [{label: "character times (the bin at 40: 40 and more)"}, {label: "responses", size: 60}],
      series: [{label: "chars"}].concat(units.map((u, i) => ({label: "unit " + u, stroke: color(i),
        fill: alpha(color(i), 0.12), paths: stepped, width: 1.5, points: {show: false}}))),
      hooks: {draw: [marks]},
    }, data, "hist");
  }

  // ---------------------------------------------------------------- registers
  function registers() {
    D.registers.plots.forEach((p, k) => {
      const S = p.series;
      make("plot-reg-" + k, timeOpts(S.map((s, i) => ({
        label: (s.label.length > 60 ? s.label.slice(0, 57) + "..." : s.label) + " (" + s.address + ")",
        stroke: color(i), paths: stepped, spanGaps: true, width: 1.5})), p.eng_unit || "value", {height: 240}),
      union(S), "time");
    });
  }

  // ---------------------------------------------------------------- timeline
  function timeline() {
    const E = D.timeline.events;
    if (!E.length) return;
    const present = new Set(E.map((e) => e.unit));
    const units = D.timeline.units.filter((u) => present.has(u));  // in the units table's order
    const row = new Map(units.map((u, i) => [u, i]));
    const OUTCOME = (e) => {
      const o = Object.keys(e.outcomes || {});
      if (o.some((k) => k.startsWith("exception"))) return "#ff7f0e";
      if (o.includes("no answer")) return "#d62728";
      return "#1f5fbf";
    };
    let rec = null;
    const draw = (u) => {
      const ctx = u.ctx, dpr = devicePixelRatio, b = u.bbox;
      let n = 0;
      ctx.save();
      ctx.beginPath();
      ctx.rect(b.left, b.top, b.width, b.height);
      ctx.clip();
      for (const e of E) {
        const y = u.valToPos(row.get(e.unit), "y", true);
        const x0 = u.valToPos(X(e.t), "x", true), x1 = u.valToPos(X(e.t_end), "x", true);
        if (e.kind === "write") {
          ctx.fillStyle = OUTCOME(e);
          if (x1 - x0 > 2 * dpr) ctx.fillRect(x0, y - 2 * dpr, x1 - x0, 4 * dpr);
          const r = 5 * dpr;
          ctx.beginPath();
          ctx.moveTo(x0, y - r); ctx.lineTo(x0 + r, y); ctx.lineTo(x0, y + r); ctx.lineTo(x0 - r, y); ctx.closePath();
          ctx.fill();
        } else {
          ctx.fillStyle = e.kind === "fault" ? "#b3261e" : "#d4a017";
          ctx.fillRect(x0, y - 9 * dpr, Math.max(x1 - x0, 3 * dpr), 6 * dpr);
        }
        n++;
      }
      ctx.restore();
      if (rec) rec.drawn += n;
    };
    const el = document.getElementById("plot-timeline");
    const hover = document.createElement("div");
    hover.className = "hover";
    const tmin = Math.min(...E.map((e) => e.t)), tmax = Math.max(D.axis.end_s, ...E.map((e) => e.t_end));
    const xs = [X(Math.min(0, tmin)), X(tmax)];
    rec = make("plot-timeline", timeOpts([{label: "events", show: false}], "unit", {
      height: Math.max(140, 60 + 34 * units.length),
      legend: {show: false},
      scales: {x: {time: clock}, y: {range: [-0.6, units.length - 0.4]}},
      axes: [timeXAxis(), {label: "unit", size: 50, splits: () => units.map((u, i) => i),
        values: (u, splits) => splits.map((i) => (/^\d+$/.test(units[i]) ? "u" : "") + units[i])}],
      hooks: {draw: [draw], setCursor: [(u) => {
        const cx = u.cursor.left, cy = u.cursor.top;
        if (cx === null || cx < 0) { hover.textContent = ""; return; }
        let best = null, bd = 12;
        for (const e of E) {
          const x0 = u.valToPos(X(e.t), "x"), x1 = u.valToPos(X(e.t_end), "x"), y = u.valToPos(row.get(e.unit), "y");
          const dx = cx < x0 ? x0 - cx : cx > x1 ? cx - x1 : 0, d = Math.hypot(dx, cy - y);
          if (d < bd) { bd = d; best = e; }
        }
        hover.textContent = best ? best.kind + " unit " + best.unit + " at " + best.t.toFixed(3) + " s (×" + best.n + "): "
          + best.text + (best.outcomes ? " → " + Object.entries(best.outcomes).map(([k, v]) => k + " ×" + v).join(", ") : "")
          : "";
      }]},
    }), [xs, [null, null]], "time");
    rec.points = E.length;
    el.appendChild(hover);
  }

  for (const f of [latency, polls, buckets, turnaround, registers, timeline]) {
    try { f(); } catch (e) { window.__report.errors.push(String(e && e.stack || e)); console.error(e); }
  }
  // uPlot sets each plot's first range in a microtask: sharing starts after those
  setTimeout(() => { syncing = false; window.__report.ready = true; }, 0);
  window.addEventListener("resize", () => {
    for (const p of plots) p.u.setSize({width: widthOf(document.getElementById(p.id)), height: p.u.height});
  });
})();
