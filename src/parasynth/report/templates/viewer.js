/* The report's interactive view (report/interactive.py gives the data): a 3D viewer of one
   design at one pose, a pose slider, a design menu, and a Pareto plot whose points switch the
   viewer to their design. Plotly is loaded by the page from the shared assets folder. */
(function () {
  "use strict";
  var D = JSON.parse(document.getElementById("viewer-data").textContent);
  var view = document.getElementById("viewer-3d");
  var par = document.getElementById("viewer-pareto");
  var menu = document.getElementById("viewer-design");
  var slider = document.getElementById("viewer-pose");
  var poseLabel = document.getElementById("viewer-pose-label");
  var info = document.getElementById("viewer-design-info");
  var xSel = document.getElementById("viewer-pareto-x");
  var ySel = document.getElementById("viewer-pareto-y");
  var U = D.length_unit;
  var state = { design: 0, pose: 0 };

  function lines(segments) {
    var x = [], y = [], z = [];
    segments.forEach(function (s) {
      s.forEach(function (p) { x.push(p[0]); y.push(p[1]); z.push(p[2]); });
      x.push(null); y.push(null); z.push(null);
    });
    return { x: x, y: y, z: z };
  }

  function line3d(name, segments, style) {
    var t = lines(segments);
    t.type = "scatter3d"; t.mode = "lines"; t.name = name; t.line = style; t.hoverinfo = "skip";
    return t;
  }

  function traces(d, k) {
    var act = [], pas = [], first = [];
    d.anchors.forEach(function (a, i) {
      (d.actuated[i] ? act : pas).push([d.B[k][i], d.A[k][i]]);
      if (d.first_joint[i]) { first.push([a, d.B[k][i]]); }
    });
    var plat = d.A[k].slice();
    if (plat.length >= 3) { plat.push(plat[0]); }
    var c = d.C[k];
    return [
      { type: "scatter3d", mode: "markers", name: "feasible workspace samples (platform centre)",
        x: d.cloud[0], y: d.cloud[1], z: d.cloud[2], hoverinfo: "skip",
        marker: { size: 2, color: "#1f77b4", opacity: 0.3 } },
      line3d(d.trajectory ? "trajectory of the platform centre" : "path of the platform centre", [d.C],
             d.trajectory ? { color: "#9467bd", width: 4 } : { color: "rgba(148,103,189,0.5)", width: 2, dash: "dot" }),
      line3d("actuated legs", act, { color: "#1f77b4", width: 7 }),
      line3d("passive legs", pas, { color: "#2ca02c", width: 7 }),
      line3d("first joint (slider or crank)", first, { color: "#555555", width: 3, dash: "dash" }),
      line3d("platform", [plat], { color: "#ff7f0e", width: 5 }),
      { type: "scatter3d", mode: "markers", name: "base anchors", hoverinfo: "skip",
        x: d.anchors.map(function (p) { return p[0]; }), y: d.anchors.map(function (p) { return p[1]; }),
        z: d.anchors.map(function (p) { return p[2]; }), marker: { size: 4, color: "#000000" } },
      { type: "scatter3d", mode: "markers", name: "platform centre", x: [c[0]], y: [c[1]], z: [c[2]],
        hovertemplate: "platform centre<br>(%{x}, %{y}, %{z}) " + U + "<extra></extra>",
        marker: { size: 5, color: "#d62728" } }
    ];
  }

  function layout3d() {
    var b = D.box, span = b.map(function (r) { return r[1] - r[0]; });
    var m = Math.max.apply(null, span);
    function ax(title, r) { return { title: { text: title + " [" + U + "]" }, range: r, autorange: false }; }
    return {
      margin: { l: 0, r: 0, t: 10, b: 0 }, uirevision: "viewer", showlegend: true,
      legend: { orientation: "h", x: 0, y: 0, bgcolor: "rgba(255,255,255,0.7)", font: { size: 11 } },
      scene: { xaxis: ax("X", b[0]), yaxis: ax("Y", b[1]), zaxis: ax("Z", b[2]), aspectmode: "manual",
               camera: { eye: { x: 1.1, y: 1.1, z: 0.8 } },
               aspectratio: { x: span[0] / m, y: span[1] / m, z: span[2] / m } }
    };
  }

  function draw3d() {
    var d = D.designs[state.design];
    Plotly.react(view, traces(d, state.pose), layout3d(), { responsive: true, displaylogo: false });
    poseLabel.textContent = "pose " + (state.pose + 1) + " of " + d.C.length + ": " + d.pose_text[state.pose];
  }

  function setPose(k) {
    state.pose = Math.max(0, Math.min(k, D.designs[state.design].C.length - 1));
    slider.value = String(state.pose);
    draw3d();
  }

  function describe(d) {
    var parts = [d.name + ": " + d.values.map(function (v) { return v[0] + " = " + v[1]; }).join(", ")];
    if (d.objectives.length) { parts.push(d.objectives.map(function (v) { return v[0] + ": " + v[1]; }).join(", ")); }
    parts.push("poses: " + d.pose_source + "; " + d.n_feasible_samples + " of " + d.n_samples +
               " workspace samples feasible");
    info.textContent = parts.join(" \u2014 ");
  }

  function setDesign(i) {
    if (i < 0 || i >= D.designs.length) { return; }
    state.design = i;
    menu.value = String(i);
    var d = D.designs[i];
    slider.max = String(d.C.length - 1);
    describe(d);
    setPose(Math.min(state.pose, d.C.length - 1));
    markSelected();
  }

  // -- the Pareto plot ---------------------------------------------------------------------------
  var P = D.pareto;
  var ix = 0, iy = P.axes.length > 1 ? 1 : 0;

  function sortedFront() {
    var f = P.front.coords, n = f[ix].length, idx = [];
    for (var i = 0; i < n; i++) { idx.push(i); }
    idx.sort(function (a, b) { return f[ix][a] - f[ix][b]; });
    return { x: idx.map(function (i) { return f[ix][i]; }), y: idx.map(function (i) { return f[iy][i]; }) };
  }

  function selectedXY() {
    var x = [], y = [], f = P.front.coords;
    P.front.design.forEach(function (d, i) { if (d === state.design) { x.push(f[ix][i]); y.push(f[iy][i]); } });
    P.marks.forEach(function (m) { if (m.design === state.design) { x.push(m.coords[ix][0]); y.push(m.coords[iy][0]); } });
    return { x: x, y: y };
  }

  function paretoTraces() {
    var t = [], bg = P.background;
    t.push({ type: "scatter", mode: "markers", name: "infeasible", x: bg.infeasible[ix], y: bg.infeasible[iy],
             hoverinfo: "skip", marker: { size: 5, color: "#d62728", opacity: 0.3 } });
    t.push({ type: "scatter", mode: "markers", name: "feasible", x: bg.feasible[ix], y: bg.feasible[iy],
             hoverinfo: "skip", marker: { size: 6, color: "#7f7f7f", opacity: 0.5 } });
    if (P.staircase && P.axes.length === 2) {
      var s = sortedFront(), shape = P.goals[ix] === "maximize" ? "vh" : "hv";
      t.push({ type: "scatter", mode: "lines", name: "front", x: s.x, y: s.y, hoverinfo: "skip", showlegend: false,
               line: { shape: shape, color: "#1f77b4", width: 1 }, opacity: 0.7 });
    }
    t.push({ type: "scatter", mode: "markers", name: "non-dominated (click: view)", x: P.front.coords[ix],
             y: P.front.coords[iy], customdata: P.front.design, text: P.front.hover,
             hovertemplate: "%{text}<extra></extra>", marker: { size: 10, color: "#1f77b4" } });
    P.marks.forEach(function (m) {
      var rec = m.role === "recommended";
      t.push({ type: "scatter", mode: "markers", name: m.name, x: m.coords[ix], y: m.coords[iy],
               customdata: [m.design], text: [m.hover], hovertemplate: "%{text}<extra></extra>",
               marker: rec ? { size: 16, symbol: "diamond-open", color: "#2ca02c", line: { width: 3 } }
                           : { size: 18, symbol: "star", color: "#ff7f0e", line: { width: 1, color: "#000000" } } });
    });
    var sel = selectedXY();
    t.push({ type: "scatter", mode: "markers", name: "in the viewer", x: sel.x, y: sel.y, hoverinfo: "skip",
             marker: { size: 24, symbol: "circle-open", color: "#d62728", line: { width: 2 } } });
    return t;
  }

  // each axis spans the feasible designs and the front (infeasible ones may lie far off: the
  // plot's autoscale button shows them all)
  function axis(i) {
    var r = P.ranges ? P.ranges[i] : null, a = { title: { text: P.axes[i].title }, zeroline: false };
    if (r) { a.range = r; a.autorange = false; }
    return a;
  }

  function drawPareto() {
    Plotly.react(par, paretoTraces(), {
      margin: { l: 70, r: 10, t: 10, b: 60 }, hovermode: "closest", uirevision: "pareto-" + ix + "-" + iy,
      xaxis: axis(ix), yaxis: axis(iy),
      legend: { orientation: "h", y: -0.2, font: { size: 11 } }
    }, { responsive: true, displaylogo: false });
  }

  function markSelected() {
    if (!par.data) { return; }
    var sel = selectedXY();
    Plotly.restyle(par, { x: [sel.x], y: [sel.y] }, [par.data.length - 1]);
  }

  function fillAxes(el, chosen) {
    P.axes.forEach(function (a, i) {
      var o = document.createElement("option");
      o.value = String(i); o.textContent = a.name; if (i === chosen) { o.selected = true; }
      el.appendChild(o);
    });
  }

  // -- wiring ------------------------------------------------------------------------------------
  D.designs.forEach(function (d, i) {
    var o = document.createElement("option");
    o.value = String(i); o.textContent = d.name;
    menu.appendChild(o);
  });
  fillAxes(xSel, ix);
  fillAxes(ySel, iy);
  if (P.axes.length <= 2) { document.getElementById("viewer-pareto-axes").style.display = "none"; }
  menu.addEventListener("change", function () { setDesign(parseInt(menu.value, 10)); });
  slider.addEventListener("input", function () { setPose(parseInt(slider.value, 10)); });
  xSel.addEventListener("change", function () { ix = parseInt(xSel.value, 10); drawPareto(); });
  ySel.addEventListener("change", function () { iy = parseInt(ySel.value, 10); drawPareto(); });
  drawPareto();
  setDesign(0);
  par.on("plotly_click", function (ev) {
    var pt = ev.points && ev.points[0];
    if (pt && typeof pt.customdata === "number" && pt.customdata >= 0) { setDesign(pt.customdata); }
  });
  view.setAttribute("data-ready", "1");
})();
