// 16-bit PNG to floats, keeping all 16 bits: browsers decode PNG to 8 bits per channel, which
// would quantize a png16 bake's texels 256 times more coarsely than the bake's error budget
// assumes. Inflates with the browser's DecompressionStream, then undoes PNG's row filters.

const SIGNATURE = [137, 80, 78, 71, 13, 10, 26, 10];
// Channels per colour type that a png16 bake writes: 6 is RGBA, 2 is RGB.
const CHANNELS = { 2: 3, 6: 4 };

/**
 * Decodes a 16-bit RGB or RGBA PNG (not interlaced) to RGBA floats in [0, 1] (value / 65535),
 * rows top-down as in the file. An RGB image gets alpha 1.
 * @param {ArrayBuffer} buffer the file's bytes
 * @param {string} name the file, for errors
 * @returns {Promise<{width: number, height: number, data: Float32Array}>}
 */
export async function decodePng16(buffer, name) {
  const bytes = new Uint8Array(buffer);
  const view = new DataView(buffer);
  if (!SIGNATURE.every((b, i) => bytes[i] === b)) throw new Error(`${name}: not a PNG file`);
  let at = 8;
  let header = null;
  const idat = [];
  while (at + 8 <= bytes.length) {
    const length = view.getUint32(at);
    const type = String.fromCharCode(...bytes.subarray(at + 4, at + 8));
    const body = bytes.subarray(at + 8, at + 8 + length);
    if (body.length !== length) throw new Error(`${name}: chunk ${type} is cut short`);
    if (type === 'IHDR') {
      header = {
        width: view.getUint32(at + 8),
        height: view.getUint32(at + 12),
        depth: bytes[at + 16],
        colour: bytes[at + 17],
        interlace: bytes[at + 20],
      };
    } else if (type === 'IDAT') {
      idat.push(body);
    } else if (type === 'IEND') {
      break;
    }
    at += 12 + length;
  }
  if (!header) throw new Error(`${name}: no IHDR chunk`);
  const channels = CHANNELS[header.colour];
  if (header.depth !== 16 || !channels || header.interlace !== 0) {
    throw new Error(
      `${name}: a ${header.depth}-bit PNG of colour type ${header.colour}` +
        `${header.interlace ? ', interlaced' : ''}; png16 bakes are 16-bit RGB(A), not interlaced`,
    );
  }
  const inflated = new Uint8Array(
    await new Response(new Blob(idat).stream().pipeThrough(new DecompressionStream('deflate'))).arrayBuffer(),
  );
  const { width, height } = header;
  const stride = width * channels * 2;
  if (inflated.length < height * (stride + 1)) throw new Error(`${name}: its image data is cut short`);
  const bpp = channels * 2;
  const rows = new Uint8Array(height * stride);
  for (let y = 0; y < height; y++) {
    const filter = inflated[y * (stride + 1)];
    const line = inflated.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    const out = rows.subarray(y * stride, (y + 1) * stride);
    const up = y > 0 ? rows.subarray((y - 1) * stride, y * stride) : null;
    for (let i = 0; i < stride; i++) {
      const a = i >= bpp ? out[i - bpp] : 0;
      const b = up ? up[i] : 0;
      const c = up && i >= bpp ? up[i - bpp] : 0;
      let predictor;
      switch (filter) {
        case 0: predictor = 0; break;
        case 1: predictor = a; break;
        case 2: predictor = b; break;
        case 3: predictor = (a + b) >> 1; break;
        case 4: {
          const p = a + b - c;
          const pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
          predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
          break;
        }
        default: throw new Error(`${name}: row ${y} has filter ${filter}, which PNG does not define`);
      }
      out[i] = (line[i] + predictor) & 0xff;
    }
  }
  const data = new Float32Array(width * height * 4);
  for (let p = 0; p < width * height; p++) {
    for (let c = 0; c < 4; c++) {
      const k = (p * channels + c) * 2;
      data[p * 4 + c] = c < channels ? ((rows[k] << 8) | rows[k + 1]) / 65535 : 1;
    }
  }
  return { width, height, data };
}
