// The page: canvas, controls and the animation loop around hooke's wasm module (pkg/, built by
// `./run web`). Every change to the cloth goes through the module's Page, which runs hooke's
// GPU solver and renderer on WebGPU.
//
// URL parameters: scene=<name>, method=<gather|scatter/...>, paused=1 (start paused; tests use
// it to run an exact number of steps).

import init, { open, scenes } from "./pkg/hooke_web.js";

const canvas = document.getElementById("canvas");
const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);

// What tests and the console can reach: the running page, and a promise of it.
const hooke = { page: null, error: null };
window.hooke = hooke;

function showError(message) {
  hooke.error = message;
  $("error").textContent = message;
  $("error").hidden = false;
  $("stats").textContent = "";
}

// Canvas pixel <-> CSS pixel: the drawing buffer follows the element's size times the device
// pixel ratio.
function canvasPixel(event) {
  const rect = canvas.getBoundingClientRect();
  return [
    ((event.clientX - rect.left) * canvas.width) / rect.width,
    ((event.clientY - rect.top) * canvas.height) / rect.height,
  ];
}
hooke.toClient = ([x, y]) => {
  const rect = canvas.getBoundingClientRect();
  return [rect.left + (x * rect.width) / canvas.width, rect.top + (y * rect.height) / canvas.height];
};

function fitCanvas() {
  const rect = canvas.getBoundingClientRect();
  const width = Math.max(1, Math.round(rect.width * devicePixelRatio));
  const height = Math.max(1, Math.round(rect.height * devicePixelRatio));
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
    hooke.page?.resize(width, height);
  }
}

function fillSelect(select, values, chosen) {
  select.replaceChildren(
    ...values.map(({ value, label }) => new Option(label ?? value, value, false, value === chosen)),
  );
}

// A new page keeps the user's pace, stiffness and drawing; wind and self-collision start as the
// scene sets them, and the controls show that.
function applyControls(page) {
  page.set_paused(paused);
  page.set_steps_per_frame(Number($("steps").value));
  page.set_stiffness_scale(10 ** Number($("stiffness").value));
  page.set_wireframe($("wireframe").checked);
  const stats = JSON.parse(page.stats());
  $("wind").checked = stats.wind.enabled;
  $("heading").value = Math.round(stats.wind.heading);
  $("speed").value = stats.wind.speed;
  $("self-collision").checked = stats.self_collision;
  for (const id of ["heading", "speed"]) $(id).dispatchEvent(new Event("input"));
}

function showControls(page) {
  const stats = JSON.parse(page.stats());
  $("balls").hidden = stats.balls === 0;
  fillSelect(
    $("method"),
    page.methods().map((value) => ({ value })),
    stats.method,
  );
  $("adapter").textContent = `GPU: ${hooke.adapter}. ${page.features().join("; ")}.`;
}

let paused = params.get("paused") === "1";
let sceneList = [];

async function start(sceneName, methodName) {
  hooke.page?.free();
  hooke.page = null;
  fitCanvas();
  const page = await open(canvas, sceneName, methodName);
  hooke.page = page;
  applyControls(page);
  const stats = JSON.parse(page.stats());
  $("description").textContent = sceneList.find((s) => s.name === stats.scene)?.description ?? "";
  showControls(page);
  return page;
}

function wireControls() {
  const onInput = (id, show, apply) => {
    $(id).addEventListener("input", () => {
      show();
      if (hooke.page) apply(hooke.page);
    });
    show();
  };
  onInput(
    "steps",
    () => ($("steps-value").textContent = $("steps").value),
    (p) => p.set_steps_per_frame(Number($("steps").value)),
  );
  onInput(
    "stiffness",
    () => ($("stiffness-value").textContent = (10 ** Number($("stiffness").value)).toFixed(2)),
    (p) => p.set_stiffness_scale(10 ** Number($("stiffness").value)),
  );
  const wind = (p) =>
    p.set_wind($("wind").checked, Number($("heading").value), Number($("speed").value));
  onInput("wind", () => {}, wind);
  onInput("heading", () => ($("heading-value").textContent = `${$("heading").value}°`), wind);
  onInput("speed", () => ($("speed-value").textContent = `${$("speed").value} m/s`), wind);
  onInput("self-collision", () => {}, (p) => p.set_self_collision($("self-collision").checked));
  onInput("wireframe", () => {}, (p) => p.set_wireframe($("wireframe").checked));

  $("pause").addEventListener("click", () => {
    paused = !paused;
    $("pause").textContent = paused ? "Run" : "Pause";
    hooke.page?.set_paused(paused);
  });
  $("pause").textContent = paused ? "Run" : "Pause";
  $("reset").addEventListener("click", () => hooke.page?.reset());
  $("scene").addEventListener("change", () =>
    start($("scene").value, $("method").value).catch((e) => showError(String(e))),
  );
  $("method").addEventListener("change", () => {
    try {
      hooke.page?.set_method($("method").value);
    } catch (e) {
      showError(String(e));
    }
  });

  for (const button of document.querySelectorAll("[data-push]")) {
    const push = (direction) => hooke.page?.push(direction);
    button.addEventListener("pointerdown", () => push(button.dataset.push));
    for (const stop of ["pointerup", "pointerleave"]) {
      button.addEventListener(stop, () => push(""));
    }
  }
  const keys = { ArrowLeft: "left", ArrowRight: "right", ArrowUp: "away", ArrowDown: "toward", PageUp: "up" };
  addEventListener("keydown", (e) => {
    if (keys[e.key] && e.target === document.body) {
      hooke.page?.push(keys[e.key]);
      e.preventDefault();
    }
  });
  addEventListener("keyup", (e) => keys[e.key] && hooke.page?.push(""));

  canvas.addEventListener("pointerdown", (e) => {
    canvas.setPointerCapture(e.pointerId);
    hooke.page?.pointer_down(...canvasPixel(e), e.button);
  });
  canvas.addEventListener("pointermove", (e) => hooke.page?.pointer_move(...canvasPixel(e)));
  for (const up of ["pointerup", "pointercancel"]) {
    canvas.addEventListener(up, () => hooke.page?.pointer_up());
  }
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener(
    "wheel",
    (e) => {
      hooke.page?.wheel(-e.deltaY / (e.deltaMode === 0 ? 100 : 1));
      e.preventDefault();
    },
    { passive: false },
  );
  new ResizeObserver(fitCanvas).observe(canvas);
}

function loop(now) {
  const page = hooke.page;
  if (page) {
    try {
      page.frame(now);
      const s = JSON.parse(page.stats());
      $("stats").textContent =
        `${s.scene} · ${s.method} · ${s.vertices} vertices, ${s.springs} springs · ` +
        `${s.fps.toFixed(0)} fps · ${Math.round(s.steps_per_second)} steps/s · ` +
        `step ${s.steps}, t = ${s.time.toFixed(2)} s` +
        (s.message ? ` · ${s.message}` : "");
    } catch (e) {
      showError(String(e));
      return;
    }
  }
  requestAnimationFrame(loop);
}

async function main() {
  if (!navigator.gpu) {
    throw new Error(
      "This browser has no WebGPU, which hooke's page needs to simulate on the GPU. " +
        "Use a current Chrome, Edge or Safari, or Firefox 141+ on Windows; on Linux, Chrome may need " +
        "chrome://flags/#enable-unsafe-webgpu. The same simulation runs natively: " +
        "`hooke view scenes/cloth-pinned.toml`.",
    );
  }
  // wgpu leaves the adapter's name empty on the web; the browser's own info names it.
  const info = (await navigator.gpu.requestAdapter())?.info;
  hooke.adapter = [info?.vendor, info?.architecture, info?.device, info?.description]
    .filter(Boolean)
    .join(" ") || "a WebGPU adapter (the browser does not name it)";
  await init();
  sceneList = JSON.parse(scenes());
  const sceneName = params.get("scene") ?? sceneList[0].name;
  fillSelect(
    $("scene"),
    sceneList.map((s) => ({ value: s.name })),
    sceneName,
  );
  wireControls();
  const page = await start(sceneName, params.get("method") ?? "gather");
  requestAnimationFrame(loop);
  return page;
}

hooke.ready = main().catch((e) => {
  showError(String(e.message ?? e));
  throw e;
});
