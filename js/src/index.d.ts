// Typings of quadsynth-client (the sources are plain ES modules; no build step).

export type Encoding = 'f32' | 'i16' | 's48' | 'delta';
export type Detail = 'full' | 'legs_spine' | 'root_gait';
export interface Lod { detail?: Detail; frame_step?: number }
export type Dtype = '<f4' | '<f8' | '<i2' | '<i4' | '|i1' | '|u1';
export type TypedArray = Float32Array | Float64Array | Int16Array | Int32Array | Int8Array | Uint8Array;

/** An array on the wire: little-endian `data`, C order. */
export interface Blob { dtype: Dtype; shape: number[]; data: Uint8Array }
export interface PackedRotations extends Blob {
  encoding: Encoding;
  decoded_shape?: number[]; // delta: what its blocks decode to
  joints?: number[]; // level of detail: the joints sent (absent: all)
  characters?: number[]; // a chunk's rows sent (absent: all)
}

export class WireError extends Error { field: string }
export class ServiceError extends Error {
  status: number; field: string; detail: string;
  /** The WebSocket close code, for stream errors (1001, 1007, 1008, 1009, 1011, 1013). */
  code?: number;
}

export function unblob(blob: Blob, field?: string): TypedArray;
export function blob(array: TypedArray, shape: number[]): Blob;
/** Unit quaternions xyzw, 4 floats per rotation, whatever the encoding. */
export function decodeRotations(rotations: PackedRotations, field?: string,
  full?: { joints?: number; characters?: number }): Float32Array;
/** delta blocks -> rotations (blocks x frames x joints x 4, xyzw). */
export function decodeDelta(bytes: Uint8Array, field?: string):
  { rotations: Float32Array; blocks: number; frames: number; joints: number };
export const DELTA_MAX_ERROR_MM: number;
export function decodeS48(bytes: Uint8Array): Float32Array;
export function decodeI16(packed: Int16Array): Float32Array;
export function contactFeet(mask: number): [boolean, boolean, boolean, boolean];
/** Worst error per encoding: [degrees, mm at a point 3 cm from the joint]. */
export const ENCODING_ERROR: Record<'f32' | 'i16' | 's48', [number, number]>;
export const FEET: ['LF', 'RF', 'LH', 'RH'];
export const GAITS: ['static', 'walk', 'trot', 'canter', 'gallop'];
export const RETRY_CODES: Set<number>;

/** GET /v1/libraries/{animal}. */
export interface LibraryDetail {
  animal: string; skeleton_id: string; fps: number; joint_names: string[]; parents: number[];
  offsets: [number, number, number][]; end_sites: boolean[]; feet: Record<'LF' | 'RF' | 'LH' | 'RH', string>;
  gaits: { index: number; name: string; min_speed: number; max_speed: number }[];
}

export class Skeleton {
  constructor(detail: LibraryDetail);
  animal: string; names: string[]; joints: number;
  parents: Int32Array; offsets: Float32Array; endSites: Uint8Array;
  feet: Record<string, string>;
  /** Joint index of each foot's end effector, LF, RF, LH, RH. */
  footJoints: number[];
  detail?: LibraryDetail;
}

/** World positions (J x 3) and rotations (J x 4) of one character at one frame; `rootAt` and
 * `rotAt` index that frame's first item in `root` and `rotations`. */
export function worldPose(skeleton: Skeleton, root: Float32Array, rootAt: number, rotations: Float32Array,
  rotAt: number, scale: number, positions?: Float32Array, worldRotations?: Float32Array):
  { positions: Float32Array; rotations: Float32Array };
/** Every joint's world matrix T(position) R(rotation) S(scale), J x 16 floats, column-major. */
export function worldMatrices(skeleton: Skeleton, root: Float32Array, rootAt: number, rotations: Float32Array,
  rotAt: number, scale: number, out?: Float32Array,
  scratch?: { positions: Float32Array; rotations: Float32Array }): Float32Array;
export function composeMatrix(out: Float32Array, at: number, px: number, py: number, pz: number,
  x: number, y: number, z: number, w: number, s: number): void;
/** World positions of the four feet of character `c` at frame `f` of a chunk. */
export function feetAt(skeleton: Skeleton, chunk: Pick<Chunk, 'frames' | 'root' | 'rotations'>, c: number, f: number,
  scale: number): [number, number, number][];

/** Frames [start, start + frames) of every character, arrays character-major. */
export interface Chunk {
  batch?: number; index: number; start: number; frames: number; characters: number; joints: number;
  encoding: Encoding;
  root: Float32Array; // characters x frames x 3, metres: joint 0's world position
  rotations: Float32Array; // characters x frames x joints x 4, local, xyzw
  gait: Int8Array; // characters x frames: 0 static, 1 walk, 2 trot, 3 canter, 4 gallop
  contacts: Uint8Array; // characters x frames: bit mask 1 LF, 2 RF, 4 LH, 8 RH
}
export function decodeChunk(message: Record<string, unknown>, header?: Record<string, unknown>): Chunk;
export function sliceChunk(chunk: Chunk, from: number): Chunk;

export interface CharacterRequest {
  id?: string; points: Float32Array | Float64Array | [number, number, number][]; scale?: number; seed?: number;
  detail?: Detail;
}
/** A height field (docs/terrain.md): the ground's y at x = origin[0] + j * spacing,
 * z = origin[1] + i * spacing for heights (nz x nx) [i][j]. */
export interface Ground { heights: Blob; origin: [number, number]; spacing: number }
/** A Ground from rows (z) of heights (x), or a Float32Array / Float64Array of nz x nx with `shape`. */
export function ground(heights: number[][] | Float32Array | Float64Array,
  options?: { origin?: [number, number]; spacing?: number; shape?: [number, number] }): Ground;
export interface SynthesizeRequest {
  characters: CharacterRequest[]; animal?: string; fps?: number; seed?: number; sigma?: number;
  encoding?: Encoding; skip_invalid?: boolean; scale_min?: number; scale_max?: number; foot_lock?: boolean;
  first_index?: number; min_resample_rate?: number; lod?: Lod;
  /** The terrain the herd walks on (the points' y then not read); one for the whole batch. */
  ground?: Ground | null;
}
export interface CharacterMotion {
  id: string; scale: number; frames: number;
  root: Float32Array; rotations: Float32Array; gait: Int8Array; contacts: Uint8Array;
}
export interface Motion {
  animal: string; skeleton_id: string; fps: number; encoding: Encoding; resample_rate: number;
  characters: CharacterMotion[]; skipped: { id: string; index: number; reason: string }[];
}
export interface LiveOptions {
  characters: { id: string; scale?: number; seed?: number; detail?: Detail }[]; fps: number; animal?: string;
  seed?: number; sigma?: number; encoding?: Encoding; lod?: Lod; scale_min?: number; scale_max?: number; foot_lock?: boolean; heading?: number;
  ground?: Ground | null;
  /** 'exact' (default): the batch's frames, seconds late; 'low_latency': each pose at most `latency_ms` after its point. */
  mode?: 'exact' | 'low_latency';
  /** The low-latency budget, 50-2000 ms (default 100); given alone it asks for 'low_latency'. */
  latency_ms?: number;
}
export interface LiveStart {
  type: 'start'; mode: 'live'; fps: number; library_fps: number; latency_frames: number; latency_s: number;
  latency_mode: 'exact' | 'low_latency'; latency_ms: number | null;
  characters: { id: string; scale: number }[];
}
export interface Codec { encode(value: unknown): Uint8Array; decode(bytes: Uint8Array): any }
export interface ClientOptions {
  webSocket?: (url: string) => WebSocket; fetch?: typeof fetch; codec?: Codec; retries?: number; retryDelayMs?: number; restRetries?: number;
}

export class QuadSynthClient {
  constructor(url: string, options?: ClientOptions);
  readonly streamUrl: string;
  readonly restRetriesMade: number;
  libraries(): Promise<{ libraries: { animal: string; joints: number; fps: number; gaits: string[] }[] }>;
  limits(): Promise<Record<string, any>>;
  skeleton(animal: string): Promise<Skeleton & { detail: LibraryDetail }>;
  synthesize(request: SynthesizeRequest): Promise<Motion>;
  /** The herd in `concurrency` requests in flight at once; the same answer as `synthesize`. */
  synthesizeSpread(request: SynthesizeRequest, options?: { concurrency?: number }): Promise<Motion>;
  stream(request: SynthesizeRequest, options?: {
    chunkFrames?: number; onStart?: (start: Record<string, any>) => void;
    onReconnect?: (info: { code?: number; error: ServiceError }) => void;
  }): AsyncGenerator<Chunk, void, void>;
  live(options: LiveOptions, handlers?: {
    onChunk?: (chunk: Chunk) => void | Promise<void>;
    onReconnect?: (info: { code?: number; error: ServiceError }) => void;
  }): Promise<LiveSession>;
}

export class LiveSession {
  header: LiveStart;
  readonly latencyFrames: number;
  /** Promise of the session's end (resolved after `finish`, rejected on an error not retried). */
  done: Promise<void>;
  /** Every character's next `n` points, characters x n x 3 floats, metres; `velocity`: each
   * point's ground velocity, characters x n x 2 floats (x, z), m/s (read by the low-latency mode). */
  push(points: Float32Array, n?: number, velocity?: Float32Array): void;
  /** The ground of the frames rendered from now on (null: the points' y), faded in over 0.4 s;
   * a reconnection opens its new session on it. */
  setGround(ground: Ground | null): void;
  finish(): Promise<void>;
  close(): void;
}
