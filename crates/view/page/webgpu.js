// The page's WebGPU path (DESIGN section 17, "In the browser"): a bake's clips played from
// their curves on the GPU, with the WGSL the native GPU path runs. Everything comes from the
// server (`/api/curves`): the playback-from-curves program and its specialization, the buffers
// uploaded once, which variables each entry point binds, and a frame's dispatches (the same
// plan as quatcurve_gpu's `ResidentCurves::frame_plan`). Per frame this writes the instances'
// records (`PlayInstance`) and submits one command buffer: the poses from the curves, forward
// kinematics per level and the skin palettes in one compute pass, then the crowd drawn by
// `palette_vertex.wgsl` reading the palettes where they lie.
'use strict';

(() => {
  // A PlayInstance: first_clip u32, second_clip u32, weight f32, pad, first_time and
  // second_time as 32.32 fixed point (lo, hi): quatcurve_gpu::playback::PlayInstance.
  const RECORD = { firstClip: 0, secondClip: 4, weight: 8, firstTime: 16, secondTime: 24 };
  // Curve times travel as whole 2^-32 s ticks (quatcurve_gpu::layout::fixed_time).
  const TICKS_PER_SECOND = 2 ** 32;
  const MSAA_SAMPLES = 4;
  const DEPTH_FORMAT = 'depth24plus';
  // Colour target: a canvas format that reads back as RGBA bytes.
  const COLOR_FORMAT = 'rgba8unorm';
  // Bytes per row of a texture copy are a multiple of this.
  const COPY_ROW_ALIGNMENT = 256;

  const decode = (base64) => Uint8Array.from(atob(base64), (c) => c.charCodeAt(0));

  // `t` seconds as [lo, hi] words of its tick count, rounded half away from zero as Rust's f64::round.
  function fixedTime(t) {
    const scaled = t * TICKS_PER_SECOND;
    const ticks = Math.sign(scaled) * Math.round(Math.abs(scaled));
    const hi = Math.floor(ticks / TICKS_PER_SECOND);
    return [ticks - hi * TICKS_PER_SECOND, hi];
  }

  // `viewProjection` (column-major, GL's clip space) with its depth moved to WebGPU's [0, 1]:
  // z' = (z + w) / 2, x and y as they are.
  function unitDepth(viewProjection) {
    const m = Float32Array.from(viewProjection);
    for (let c = 0; c < 4; c++) m[c * 4 + 2] = 0.5 * (viewProjection[c * 4 + 2] + viewProjection[c * 4 + 3]);
    return m;
  }

  async function compiled(device, code, what) {
    const module = device.createShaderModule({ code });
    const info = await module.getCompilationInfo();
    const errors = info.messages.filter((m) => m.type === 'error');
    if (errors.length) throw new Error(`${what}: ${errors.map((m) => `${m.lineNum}:${m.linePos} ${m.message}`).join('; ')}`);
    return module;
  }

  class CurvePlayer {
    // A device with the storage bindings the playback program needs, or why there is none.
    static async device() {
      if (!navigator.gpu) return { reason: 'this browser has no WebGPU' };
      const adapter = await navigator.gpu.requestAdapter();
      if (!adapter) return { reason: 'no WebGPU adapter' };
      const wanted = ['maxStorageBuffersPerShaderStage', 'maxStorageBufferBindingSize', 'maxBufferSize'];
      const requiredLimits = Object.fromEntries(wanted.map((k) => [k, adapter.limits[k]]));
      const device = await adapter.requestDevice({ requiredLimits });
      const { vendor, architecture, description } = adapter.info || {};
      return { device, name: [vendor, architecture, description].filter(Boolean).join(' ') || 'WebGPU adapter' };
    }

    constructor(device, canvas, antialias) {
      this.device = device;
      this.canvas = canvas;
      this.samples = antialias ? MSAA_SAMPLES : 1;
      this.context = canvas.getContext('webgpu');
      this.context.configure({
        device, format: COLOR_FORMAT, alphaMode: 'opaque',
        usage: GPUTextureUsage.RENDER_ATTACHMENT | GPUTextureUsage.COPY_SRC,
      });
      this.errors = [];
      device.addEventListener('uncapturederror', (e) => this.errors.push(e.error.message));
      device.lost.then((info) => this.errors.push(`the device was lost: ${info.message}`));
    }

    // Uploads `curves` (an /api/curves answer) and builds the programs for `scene`'s draws.
    async load(curves, scene, notes) {
      const { device } = this;
      const compute = await compiled(device, curves.compute_shader, 'the playback program');
      this.pipelines = {};
      for (const { entry } of curves.entries) {
        // The specialization is the pose kernel's; the other entry points use no override.
        const constants = entry === curves.entries[0].entry ? curves.constants : {};
        this.pipelines[entry] = await device.createComputePipelineAsync({
          layout: 'auto', compute: { module: compute, entryPoint: entry, constants },
        });
      }
      this.resident = {};
      for (const b of curves.buffers) this.resident[b.name] = this.buffer(decode(b.base64), b.uniform);
      const vertex = await compiled(device, curves.vertex_shader, 'the palette vertex shader');
      const fragment = await compiled(device, curves.fragment_shader, 'the fragment shader');
      const drawn = scene.draws.filter((d) => curves.skins.includes(d.skin));
      const first = drawn[0];
      if (!first) throw new Error(`no primitive of skin ${curves.skins[0]} to draw`);
      const format = (a) => `${a.integer ? 'uint32' : 'float32'}${a.size > 1 ? `x${a.size}` : ''}`;
      const layouts = first.attributes.map((a) => ({
        arrayStride: 4 * a.size, stepMode: 'vertex', attributes: [{ shaderLocation: a.location, offset: 0, format: format(a) }],
      }));
      layouts.push({ arrayStride: 12, stepMode: 'instance',
        attributes: [{ shaderLocation: scene.instance.offset, offset: 0, format: 'float32x3' }] });
      this.render = device.createRenderPipeline({
        layout: 'auto',
        vertex: { module: vertex, entryPoint: curves.vertex_entry, buffers: layouts },
        fragment: { module: fragment, entryPoint: curves.fragment_entry, targets: [{ format: COLOR_FORMAT }] },
        primitive: { topology: 'triangle-list' },
        depthStencil: { format: DEPTH_FORMAT, depthWriteEnabled: true, depthCompare: 'less' },
        multisample: { count: this.samples },
      });
      this.draws = drawn.map((d) => ({
        count: d.indices.length,
        vertices: d.attributes.map((a) => this.buffer(new Uint8Array(
          (a.integer ? Uint32Array.from(a.data) : Float32Array.from(a.data)).buffer), false, GPUBufferUsage.VERTEX)),
        indices: this.buffer(new Uint8Array(Uint32Array.from(d.indices).buffer), false, GPUBufferUsage.INDEX),
      }));
      for (const d of scene.draws.filter((d) => !curves.skins.includes(d.skin))) notes.push(`${d.name}: not drawn (another skin)`);
      this.camera = device.createBuffer({ size: 64, usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST });
      this.paletteLayout = this.buffer(new Uint8Array(new Uint32Array([curves.skin_joints, 0, 0, 0]).buffer), true);
      this.frameBuffers(curves);
      await this.check('loading the curves');
    }

    // A buffer holding `bytes` (padded to whole words): a uniform, else storage, or `usage`.
    buffer(bytes, uniform, usage) {
      const size = Math.max(16, Math.ceil(bytes.byteLength / 4) * 4);
      const kind = usage || (uniform ? GPUBufferUsage.UNIFORM : GPUBufferUsage.STORAGE);
      const buffer = this.device.createBuffer({ size, usage: kind | GPUBufferUsage.COPY_DST, mappedAtCreation: true });
      new Uint8Array(buffer.getMappedRange()).set(bytes);
      buffer.unmap();
      return buffer;
    }

    // The frame's buffers and bind groups for `curves.instances` instances (its plan).
    frameBuffers(curves) {
      const { device } = this;
      this.curves = curves;
      const n = curves.instances;
      for (const b of this.owned || []) b.destroy();
      const storage = (bytes) => device.createBuffer({ size: Math.max(16, bytes), usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_DST });
      this.records = storage(n * curves.instance_bytes);
      this.recordBytes = new ArrayBuffer(n * curves.instance_bytes);
      const byRole = Object.fromEntries(Object.entries(curves.frame_floats).map(([role, floats]) => [role, storage(4 * n * floats)]));
      this.offsets = device.createBuffer({ size: Math.max(16, 12 * n), usage: GPUBufferUsage.VERTEX | GPUBufferUsage.COPY_DST });
      this.owned = [this.records, this.offsets, ...Object.values(byRole)];
      const bindings = Object.fromEntries(curves.entries.map((e) => [e.entry, e.bindings]));
      this.dispatches = curves.dispatches.map((d) => {
        const perDispatch = {
          play_params: this.buffer(new Uint8Array(new Uint32Array(d.params).buffer), true),
          fk_level: d.level ? this.buffer(new Uint8Array(new Uint32Array(d.level).buffer), true) : null,
          play_instances: this.records,
        };
        this.owned.push(perDispatch.play_params, ...(perDispatch.fk_level ? [perDispatch.fk_level] : []));
        const pipeline = this.pipelines[d.entry];
        const entries = bindings[d.entry].map(({ name, binding }) => {
          const buffer = this.resident[name] || byRole[curves.frame_roles[name]] || perDispatch[name];
          if (!buffer) throw new Error(`${d.entry} binds \`${name}\`, which the page does not have`);
          return { binding, resource: { buffer } };
        });
        return { pipeline, groups: d.groups, group: device.createBindGroup({ layout: pipeline.getBindGroupLayout(0), entries }) };
      });
      const resources = { palette_camera: this.camera, palette_matrices: byRole.palettes, palette_layout: this.paletteLayout };
      this.renderGroup = device.createBindGroup({
        layout: this.render.getBindGroupLayout(0),
        entries: curves.vertex_bindings.map(({ name, binding }) => ({ binding, resource: { buffer: resources[name] } })),
      });
      this.instances = n;
      this.targets = null;
    }

    // Where the instances stand (x, y, z each).
    place(offsets) {
      this.device.queue.writeBuffer(this.offsets, 0, new Float32Array(offsets));
    }

    // The curves' time of a pose `t` seconds into clip `c`: an open clip's held to its span.
    curveTime(c, t) {
      const clip = this.curves.clips[c];
      return clip.start + (clip.looping ? t : Math.min(Math.max(t, 0), clip.duration));
    }

    // One frame: instance i plays `clip` at `times[i]`, blended towards `blend` at the same
    // phase of that clip by `weight` (play's rule, `schedule::same_phase`); drawn with
    // `viewProjection` (GL's clip space).
    draw(clip, blend, weight, times, viewProjection, clear) {
      const { device } = this;
      const view = new DataView(this.recordBytes);
      const size = this.curves.instance_bytes;
      const [a, b] = [this.curves.clips[clip].duration, this.curves.clips[blend].duration];
      for (let i = 0; i < this.instances; i++) {
        const at = i * size;
        const second = a > 0 ? (times[i] / a) * b : 0;
        view.setUint32(at + RECORD.firstClip, clip, true);
        view.setUint32(at + RECORD.secondClip, blend, true);
        view.setFloat32(at + RECORD.weight, weight, true);
        for (const [offset, c, t] of [[RECORD.firstTime, clip, times[i]], [RECORD.secondTime, blend, second]]) {
          const [lo, hi] = fixedTime(this.curveTime(c, t));
          view.setUint32(at + offset, lo, true);
          view.setInt32(at + offset + 4, hi, true);
        }
      }
      device.queue.writeBuffer(this.records, 0, this.recordBytes);
      device.queue.writeBuffer(this.camera, 0, unitDepth(viewProjection));
      const encoder = device.createCommandEncoder();
      const pass = encoder.beginComputePass();
      for (const d of this.dispatches) {
        pass.setPipeline(d.pipeline);
        pass.setBindGroup(0, d.group);
        pass.dispatchWorkgroups(d.groups[0], d.groups[1]);
      }
      pass.end();
      const texture = this.context.getCurrentTexture();
      const targets = this.renderTargets(texture);
      const render = encoder.beginRenderPass({
        colorAttachments: [{
          view: targets.color ? targets.color.createView() : texture.createView(),
          resolveTarget: targets.color ? texture.createView() : undefined,
          clearValue: clear, loadOp: 'clear', storeOp: 'store',
        }],
        depthStencilAttachment: { view: targets.depth.createView(), depthClearValue: 1, depthLoadOp: 'clear', depthStoreOp: 'discard' },
      });
      render.setPipeline(this.render);
      render.setBindGroup(0, this.renderGroup);
      for (const d of this.draws) {
        d.vertices.forEach((v, k) => render.setVertexBuffer(k, v));
        render.setVertexBuffer(d.vertices.length, this.offsets);
        render.setIndexBuffer(d.indices, 'uint32');
        render.drawIndexed(d.count, this.instances);
      }
      render.end();
      device.queue.submit([encoder.finish()]);
      // A frame loop draws again only once this one is done: a GPU slower than the display
      // would otherwise queue frames without end.
      this.pending = device.queue.onSubmittedWorkDone().finally(() => { this.pending = null; });
      return texture;
    }

    // Whether a frame is still on the GPU.
    busy() {
      return Boolean(this.pending);
    }

    // Depth (and multisampled colour) targets the size of `texture`, kept while it keeps its size.
    renderTargets(texture) {
      const { width, height } = texture;
      if (!this.targets || this.targets.width !== width || this.targets.height !== height) {
        const make = (format) => this.device.createTexture({
          size: [width, height], format, sampleCount: this.samples, usage: GPUTextureUsage.RENDER_ATTACHMENT,
        });
        this.targets = { width, height, depth: make(DEPTH_FORMAT), color: this.samples > 1 ? make(COLOR_FORMAT) : null };
      }
      return this.targets;
    }

    // `texture` (just drawn) read back: RGBA8 rows from the bottom, as GL's readPixels.
    async read(texture) {
      const { width, height } = texture;
      const row = Math.ceil((4 * width) / COPY_ROW_ALIGNMENT) * COPY_ROW_ALIGNMENT;
      const staging = this.device.createBuffer({ size: row * height, usage: GPUBufferUsage.COPY_DST | GPUBufferUsage.MAP_READ });
      const encoder = this.device.createCommandEncoder();
      encoder.copyTextureToBuffer({ texture }, { buffer: staging, bytesPerRow: row }, [width, height]);
      this.device.queue.submit([encoder.finish()]);
      await staging.mapAsync(GPUMapMode.READ);
      const rows = new Uint8Array(staging.getMappedRange());
      const pixels = new Uint8Array(width * height * 4);
      for (let y = 0; y < height; y++) pixels.set(rows.subarray(y * row, y * row + 4 * width), (height - 1 - y) * 4 * width);
      staging.unmap();
      staging.destroy();
      await this.check('drawing');
      return pixels;
    }

    // Waits for the queue; throws the device's errors so far.
    async check(what) {
      await this.device.queue.onSubmittedWorkDone();
      if (this.errors.length) throw new Error(`WebGPU, ${what}: ${this.errors.join('; ')}`);
    }
  }

  window.QuatcurveCurvePlayer = CurvePlayer;
})();
