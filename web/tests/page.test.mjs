// The page in a real browser: Debian's Chromium, headless, WebGPU on SwiftShader (a CPU
// implementation of Vulkan), driven by playwright-core. Needs the built page (web/pkg, from
// `./run web --build-only`) and the native `hooke` binary (HOOKE_BIN) for the comparison.
//
// HOOKE_WEB_SCREENSHOT=path saves the page's screenshot there (README's picture).

import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { mkdtempSync, readFileSync, writeFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, dirname } from "node:path";
import { after, before, describe, test } from "node:test";
import { fileURLToPath } from "node:url";

import httpServer from "http-server";
import { chromium } from "playwright-core";
import { PNG } from "pngjs";

// http-server 14 uses an API node deprecated; the warning says nothing about the page.
process.noDeprecation = true;

const webRoot = dirname(dirname(fileURLToPath(import.meta.url)));
const repoRoot = dirname(webRoot);
const hookeBin = process.env.HOOKE_BIN ?? join(repoRoot, "target/debug/hooke");

// Flags that give headless Chromium WebGPU without a GPU, and let a canvas be read back.
const CHROMIUM_ARGS = [
  "--headless",
  "--no-sandbox",
  "--enable-unsafe-webgpu",
  "--enable-features=Vulkan",
  "--use-vulkan=swiftshader",
  "--use-webgpu-adapter=swiftshader",
  "--use-angle=swiftshader",
  "--disable-background-networking",
  "--disable-component-update",
  "--disable-sync",
  "--disable-quic",
  "--no-first-run",
];

let server;
let origin;
let browser;

before(async () => {
  server = httpServer.createServer({ root: webRoot, cache: -1, showDir: false, logFn: () => {} });
  await new Promise((resolve) => server.listen(0, "127.0.0.1", resolve));
  origin = `http://127.0.0.1:${server.server.address().port}`;
  browser = await chromium.launch({
    executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
    args: CHROMIUM_ARGS,
  });
});

after(async () => {
  await browser?.close();
  server?.close();
});

/** Opens the page with `query`, waits for it to start, and collects console errors. */
async function openPage(query, size = { width: 1200, height: 720 }) {
  const context = await browser.newContext({ viewport: size, deviceScaleFactor: 1 });
  const page = await context.newPage();
  const errors = [];
  page.on("console", (m) => m.type() === "error" && errors.push(m.text()));
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(`${origin}/index.html?${query}`);
  await page.evaluate(() => window.hooke.ready);
  return { page, errors, close: () => context.close() };
}

// Null while the page switches scenes (the old simulation is gone, the new one not yet there).
const stats = (page) =>
  page.evaluate(() => (window.hooke.page ? JSON.parse(window.hooke.page.stats()) : null));

/** Waits until `predicate(stats)` holds, checking once per animation frame or so. */
async function waitFor(page, predicate, what, timeoutMs = 60_000) {
  const start = Date.now();
  for (;;) {
    const s = await stats(page);
    if (s && predicate(s)) return s;
    assert.ok(Date.now() - start < timeoutMs, `timed out waiting for ${what}: ${JSON.stringify(s)}`);
    await page.waitForTimeout(50);
  }
}

/** `x y z` per vertex from the page's GPU buffer. */
async function pagePositions(page) {
  return page.evaluate(async () => Array.from(await window.hooke.page.positions()));
}

/** Positions (x, y, z per vertex) of `hooke run`'s final-state.ply (binary, float64). */
function readFinalState(path) {
  const bytes = readFileSync(path);
  const end = bytes.indexOf("end_header\n");
  const header = bytes.subarray(0, end).toString("latin1").split("\n");
  const count = Number(header.find((l) => l.startsWith("element vertex")).split(" ")[2]);
  const properties = [];
  for (const line of header.slice(header.findIndex((l) => l.startsWith("element vertex")) + 1)) {
    if (!line.startsWith("property")) break;
    const [, type, name] = line.split(" ");
    assert.equal(type, "double", `final-state.ply property ${name}`);
    properties.push(name);
  }
  const data = new DataView(bytes.buffer, bytes.byteOffset + end + "end_header\n".length);
  const xyz = ["x", "y", "z"].map((n) => properties.indexOf(n));
  const positions = [];
  for (let v = 0; v < count; v++) {
    for (const k of xyz) positions.push(data.getFloat64(8 * (v * properties.length + k), true));
  }
  return positions;
}

/** `hooke run`'s positions after `steps` steps of `scene` on the native GPU solver. */
function nativePositions(scene, method, steps) {
  const out = mkdtempSync(join(tmpdir(), "hooke-web-"));
  try {
    const [backendMethod, accumulation] = method.split("/");
    const args = ["run", join(repoRoot, "scenes", `${scene}.toml`), "--backend", "gpu"];
    args.push("--method", backendMethod, "--steps", String(steps), "--no-frames");
    args.push("--output", out);
    if (accumulation) args.push("--accumulation", accumulation);
    execFileSync(hookeBin, args, { stdio: ["ignore", "ignore", "pipe"] });
    return readFinalState(join(out, "final-state.ply"));
  } finally {
    rmSync(out, { recursive: true, force: true });
  }
}

/** Largest distance between corresponding vertices, m. */
function maxDistance(a, b) {
  assert.equal(a.length, b.length);
  let worst = 0;
  for (let i = 0; i < a.length; i += 3) {
    worst = Math.max(worst, Math.hypot(a[i] - b[i], a[i + 1] - b[i + 1], a[i + 2] - b[i + 2]));
  }
  return worst;
}

describe("hooke's page in headless Chromium (WebGPU on SwiftShader)", () => {
  test("loads without console errors, reports its adapter and runs", async () => {
    const { page, errors, close } = await openPage("scene=wind-and-balls&method=gather");
    try {
      const adapter = await page.evaluate(() => window.hooke.adapter);
      assert.match(adapter, /swiftshader/i);
      assert.match(await page.evaluate(() => window.hooke.page.adapter()), /BrowserWebGpu/);
      assert.match(await page.textContent("#adapter"), /GPU: .+/);
      const methods = await page.evaluate(() => window.hooke.page.methods());
      assert.ok(methods.includes("gather") && methods.includes("scatter/atomic-fixed"), methods);
      assert.ok(!methods.includes("scatter/atomic-f32"), "WebGPU has no float atomics");
      const running = await waitFor(page, (s) => s.steps >= 100, "100 steps");
      assert.equal(running.balls, 3);
      assert.equal(running.wind.enabled, true, "the scene's wind is on");
      assert.match(await page.textContent("#stats"), /fps .* steps\/s/);
      console.log(`adapter: ${adapter}; methods: ${methods.join(", ")}`);

      // The controls: another method restarts the scene on it; another scene replaces it.
      await page.selectOption("#method", "scatter/atomic-fixed");
      await waitFor(
        page,
        (s) => s.method === "scatter/atomic-fixed" && s.steps >= 20,
        "the method switch",
      );
      await page.selectOption("#scene", "self-collision");
      const folded = await waitFor(
        page,
        (s) => s.scene === "self-collision" && s.steps >= 20,
        "the scene switch",
      );
      assert.equal(folded.method, "scatter/atomic-fixed");
      assert.equal(folded.self_collision, true, "Fig. 3's self-collision is on");
      assert.equal(await page.isChecked("#self-collision"), true);
      assert.equal(await page.isHidden("#balls"), true, "no ball to push in Fig. 3");
      assert.deepEqual(errors, []);
    } finally {
      await close();
    }
  });

  // Positions after STEPS steps of the paper's Fig. 2 scene. The browser (SwiftShader) and
  // the native solver (Mesa's lavapipe) compute in float32 with different instruction
  // choices, so they agree to rounding, not bit for bit. The bar is checked against two
  // runs that are wrong: one step too few, and springs 1% too stiff.
  const STEPS = 300;
  const TOLERANCE = 1e-5; // m, on a 1 m cloth

  for (const method of ["gather", "scatter/incidence", "scatter/atomic-fixed"]) {
    test(`${STEPS} steps of ${method} agree with the native GPU solver`, async () => {
      const native = nativePositions("cloth-pinned", method, STEPS);
      const { page, errors, close } = await openPage(`scene=cloth-pinned&method=${method}&paused=1`);
      try {
        const initial = await pagePositions(page);
        await page.evaluate((n) => window.hooke.page.step(n), STEPS - 1);
        const oneShort = await pagePositions(page);
        await page.evaluate(() => window.hooke.page.step(1));
        const positions = await pagePositions(page);
        assert.equal((await stats(page)).steps, STEPS);
        await page.evaluate(() => window.hooke.page.reset());
        await page.evaluate(() => window.hooke.page.set_stiffness_scale(1.01));
        await page.evaluate((n) => window.hooke.page.step(n), STEPS);
        const stiffer = await pagePositions(page);

        const error = maxDistance(positions, native);
        const moved = maxDistance(positions, initial);
        const broken = {
          "one step short": maxDistance(oneShort, native),
          "stiffness 1% off": maxDistance(stiffer, native),
        };
        console.log(
          `${method}: page vs native ${error.toExponential(2)} m after ${STEPS} steps; ` +
            `moved ${moved.toExponential(2)} m; broken: ` +
            Object.entries(broken)
              .map(([k, v]) => `${k} ${v.toExponential(2)}`)
              .join(", "),
        );
        assert.ok(moved > 1e-3, `the cloth moved (${moved})`);
        assert.ok(error < TOLERANCE, `page vs native: ${error} m`);
        for (const [name, score] of Object.entries(broken)) {
          assert.ok(score > TOLERANCE, `the bar must reject "${name}" (${score} m)`);
        }
        assert.deepEqual(errors, []);
      } finally {
        await close();
      }
    });
  }

  test("draws a cloth (a screenshot of the canvas is not blank)", async () => {
    const { page, errors, close } = await openPage("scene=cloth-pinned&method=gather");
    try {
      await waitFor(page, (s) => s.steps >= 600, "600 steps");
      const png = PNG.sync.read(await page.locator("#canvas").screenshot());
      let cloth = 0;
      for (let i = 0; i < png.data.length; i += 4) {
        // The cloth's salmon checker; the background and ground are grey.
        if (png.data[i] - png.data[i + 1] > 40) cloth++;
      }
      const share = cloth / (png.width * png.height);
      console.log(`cloth covers ${(100 * share).toFixed(1)}% of the ${png.width}x${png.height} canvas`);
      assert.ok(share > 0.05, `cloth pixels: ${cloth}`);
      if (process.env.HOOKE_WEB_SCREENSHOT) {
        writeFileSync(process.env.HOOKE_WEB_SCREENSHOT, await page.screenshot());
      }
      assert.deepEqual(errors, []);
    } finally {
      await close();
    }
  });

  test("a mouse drag moves the grabbed vertex toward the cursor", async () => {
    const { page, errors, close } = await openPage("scene=cloth-pinned&method=gather");
    try {
      await waitFor(page, (s) => s.steps >= 300, "300 steps");
      // The vertex nearest the cloth's centre, where the canvas draws it now.
      const positions = await pagePositions(page);
      const n = positions.length / 3;
      const middle = Math.floor(n / 2) + 32; // row 32, column 32 of the 64 x 64 grid
      const at = positions.slice(3 * middle, 3 * middle + 3);
      const pixel = await page.evaluate(([x, y, z]) => window.hooke.page.project(x, y, z), at);
      const [cx, cy] = await page.evaluate((p) => window.hooke.toClient(p), pixel);
      await page.mouse.move(cx, cy);
      await page.mouse.down();
      const held = await waitFor(page, (s) => s.holding !== null, "the pick");
      const vertex = held.holding;
      const start = (await pagePositions(page)).slice(3 * vertex, 3 * vertex + 3);
      for (let k = 1; k <= 10; k++) await page.mouse.move(cx + 15 * k, cy - 10 * k);
      const moved = await waitFor(page, (s) => s.steps >= held.steps + 600, "600 more steps");
      const target = moved.grab_target;
      const end = (await pagePositions(page)).slice(3 * vertex, 3 * vertex + 3);
      const distance = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
      console.log(
        `grabbed vertex ${vertex}: ${distance(start, target).toFixed(3)} m from the cursor's ` +
          `target at the grab, ${distance(end, target).toFixed(3)} m after 600 steps`,
      );
      assert.ok(distance(start, target) > 0.05, "the cursor moved away from the vertex");
      assert.ok(distance(end, target) < 0.5 * distance(start, target), "it followed the cursor");
      await page.mouse.up();
      await waitFor(page, (s) => s.holding === null && s.grab_target === null, "the release");
      assert.deepEqual(errors, []);
    } finally {
      await close();
    }
  });

  test("without WebGPU the page says so", async () => {
    const context = await browser.newContext();
    const page = await context.newPage();
    try {
      await page.addInitScript(() => delete Object.getPrototypeOf(navigator).gpu);
      await page.goto(`${origin}/index.html`);
      await page.waitForSelector("#error:not([hidden])");
      assert.match(await page.textContent("#error"), /no WebGPU/);
    } finally {
      await context.close();
    }
  });
});
