// quadsynth-client: see README.md beside package.json and docs/play-the-stream.md.
export { QuadSynthClient, LiveSession, ServiceError, RETRY_CODES, decodeChunk, sliceChunk, ground } from './client.js';
export { Skeleton, worldPose, worldMatrices, composeMatrix, feetAt } from './pose.js';
export { unblob, blob, decodeRotations, decodeS48, decodeI16, decodeDelta, contactFeet, WireError, ENCODING_ERROR, DELTA_MAX_ERROR_MM, FEET, GAITS } from './wire.js';
