// The middle of a list of numbers: the frame-cost, latency and joint-interval windows use it, as
// one slow frame or late state must not swing what the view decides.

/** The median of ``values`` (the upper one of an even count), or null for none. */
export function median(values) {
  if (!values.length) return null;
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.floor(sorted.length / 2)];
}
