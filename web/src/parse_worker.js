// Parses the server's frames off the page's main thread. A snapshot of ten thousand bodies
// is over a megabyte of JSON, and parsing it there would hold up drawing for a frame or
// more, thirty times a second. Frames come back in the order they were sent, with each
// snapshot's columns transferred, not copied.
import { parse_frame, transferables } from './parse_frame.js';

self.onmessage = (event) => {
  const { generation, data, received_at } = event.data;
  const parsed = parse_frame(data, received_at);
  self.postMessage({ generation, parsed }, transferables(parsed));
};
