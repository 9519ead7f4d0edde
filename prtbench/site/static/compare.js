// The scene page's image comparison: method vs reference with a wipe, click/hover flip,
// keyboard stepping through configurations and views, exposure stops, FLIP map layer.
// Full-size images load only when shown (thumbnails are lazy <img>s in the table).
(function () {
  "use strict";
  const source = document.getElementById("compare-data");
  if (!source) return;
  const data = JSON.parse(source.textContent);
  const $ = (id) => document.getElementById(id);
  const top = $("cmp-top"), ref = $("cmp-reference"), wipe = $("cmp-wipe"), line = $("cmp-line");
  const stage = $("cmp-stage"), label = $("cmp-label"), configSelect = $("cmp-config");
  const viewSelect = $("cmp-view"), hover = $("cmp-hover");
  const configs = data.configs.filter((c) => Object.keys(c.views).length > 0);
  const state = { index: 0, view: String(data.views[0]), ev: "0", layer: "method", wipe: 50,
                  saved: null };

  configs.forEach((c, i) => {
    const option = document.createElement("option");
    option.value = String(i);
    option.textContent = `${c.id}: ${c.label}`;
    configSelect.appendChild(option);
  });
  data.views.forEach((v) => {
    const option = document.createElement("option");
    option.value = String(v);
    option.textContent = String(v);
    viewSelect.appendChild(option);
  });

  function images() {
    const c = configs[state.index];
    return c.views[state.view] || c.views[Object.keys(c.views)[0]];
  }

  function show() {
    const c = configs[state.index];
    if (!c.views[state.view]) state.view = Object.keys(c.views)[0];
    const im = images();
    const topSrc = state.layer === "flip" ? im.flip : im.method[state.ev];
    if (top.getAttribute("src") !== topSrc) top.setAttribute("src", topSrc);
    if (ref.getAttribute("src") !== im.reference[state.ev]) ref.setAttribute("src", im.reference[state.ev]);
    top.style.clipPath = `inset(0 ${100 - state.wipe}% 0 0)`;
    line.style.left = `${state.wipe}%`;
    line.style.display = state.wipe > 0 && state.wipe < 100 ? "block" : "none";
    wipe.value = String(state.wipe);
    configSelect.value = String(state.index);
    viewSelect.value = state.view;
    document.querySelectorAll("button.ev").forEach((b) =>
      b.classList.toggle("active", b.dataset.ev === state.ev));
    document.querySelectorAll('input[name="cmp-layer"]').forEach((r) => { r.checked = r.value === state.layer; });
    const what = state.wipe >= 100 ? (state.layer === "flip" ? "FLIP map" : "method")
      : state.wipe <= 0 ? "reference" : `${state.layer === "flip" ? "FLIP map" : "method"} | reference`;
    label.textContent = `${c.id} ${c.label}, view ${state.view}, ${Number(state.ev) >= 0 ? "+" : ""}${state.ev} EV: ${what}`;
    stage.dataset.showing = what;
    document.querySelectorAll("tr.selected").forEach((r) => r.classList.remove("selected"));
    const row = document.getElementById(c.id);
    if (row) row.classList.add("selected");
  }

  function select(id, view) {
    const i = configs.findIndex((c) => c.id === id);
    if (i < 0) return false;
    state.index = i;
    if (view !== undefined) state.view = String(view);
    show();
    return true;
  }
  function step(delta) { state.index = (state.index + delta + configs.length) % configs.length; show(); }
  function flip() { state.wipe = state.wipe >= 50 ? 0 : 100; show(); }
  function exposure(delta) {
    const stops = data.stops.map(String);
    const i = Math.min(stops.length - 1, Math.max(0, stops.indexOf(state.ev) + delta));
    state.ev = stops[i];
    show();
  }

  wipe.addEventListener("input", () => { state.wipe = Number(wipe.value); show(); });
  stage.addEventListener("click", flip);
  stage.addEventListener("mouseenter", () => {
    if (!hover.checked) return;
    state.saved = state.wipe; state.wipe = 0; show();
  });
  stage.addEventListener("mouseleave", () => {
    if (state.saved === null) return;
    state.wipe = state.saved; state.saved = null; show();
  });
  $("cmp-prev").addEventListener("click", () => step(-1));
  $("cmp-next").addEventListener("click", () => step(1));
  configSelect.addEventListener("change", () => { state.index = Number(configSelect.value); show(); });
  viewSelect.addEventListener("change", () => { state.view = viewSelect.value; show(); });
  document.querySelectorAll("button.ev").forEach((b) =>
    b.addEventListener("click", () => { state.ev = b.dataset.ev; show(); }));
  document.querySelectorAll('input[name="cmp-layer"]').forEach((r) =>
    r.addEventListener("change", () => { state.layer = r.value; show(); }));
  document.querySelectorAll("[data-config].thumb, button.show").forEach((el) =>
    el.addEventListener("click", () => { select(el.dataset.config, el.dataset.view); }));
  document.addEventListener("keydown", (event) => {
    if (event.target.closest && event.target.closest("input, select, textarea")) return;
    const actions = {
      ArrowRight: () => step(1), j: () => step(1), ArrowLeft: () => step(-1), k: () => step(-1),
      f: flip, " ": flip, e: () => { state.layer = state.layer === "flip" ? "method" : "flip"; show(); },
      "+": () => exposure(1), "=": () => exposure(1), "-": () => exposure(-1),
      "0": () => { state.ev = "0"; show(); },
      v: () => {
        const views = Object.keys(configs[state.index].views);
        state.view = views[(views.indexOf(state.view) + 1) % views.length]; show();
      },
    };
    const action = actions[event.key];
    if (action) { event.preventDefault(); action(); }
  });

  // The Pareto plot (pareto.js) and links (#c003) open a configuration's images.
  window.prtbenchCompare = { select: (id) => { const ok = select(id); if (ok) stage.scrollIntoView({ block: "nearest" }); return ok; } };
  if (!configs.length) return;
  if (!(location.hash && select(location.hash.slice(1)))) show();
})();
