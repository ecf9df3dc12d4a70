// Parses the server's frames off the page's main thread. A snapshot of ten thousand bodies
// is over a megabyte of JSON in the full form, and parsing it (or applying a compact delta
// to ten thousand bodies) there would hold up drawing for a frame or more, thirty times a
// second. Frames come back in the order they were sent, with each snapshot's columns
// transferred, not copied. The worker holds the compact stream's state: a new socket (a new
// generation) starts from nothing, so its first delta before a keyframe is refused.
import { CompactStream } from './compact.js';
import { parse_frame, transferables } from './parse_frame.js';

let generation = null;
let stream = new CompactStream();

self.onmessage = (event) => {
  const { data, received_at } = event.data;
  if (event.data.generation !== generation) {
    generation = event.data.generation;
    stream = new CompactStream();
  }
  const parsed = parse_frame(data, received_at, stream);
  self.postMessage({ generation, parsed }, transferables(parsed));
};
