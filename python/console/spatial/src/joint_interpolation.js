// The drawn arm between the joint states the habitat sends. The ground server forwards them at a
// bounded rate (10/s over the link), so drawing each one as it comes shows the arm jump ten times a
// second. Instead each new state starts a straight move in joint space from what is drawn to it,
// lasting the stream's usual interval: the arm moves at the view's frame rate and reaches each state
// as the next one is due. Every drawn value lies between two states the arm really passed through;
// nothing is extrapolated, so an arm that halts is never drawn beyond where it stopped. The cost is
// at most one interval (100 ms at 10/s) more delay than drawing each state as it arrives.

import { median } from './median.js';

const INTERVAL_WINDOW = 5;
// A state that follows the previous one after longer than this is not part of a stream (the first
// state, a single update, a stream that stalled): it is drawn at once.
const STREAM_GAP_MS = 300;

export class JointInterpolation {
  /** @param {(name: string) => boolean} wraps whether a joint is continuous (goes the short way round) */
  constructor(wraps = () => false) {
    this.wraps = wraps;
    this._lastArrival = null;
    this._intervals = []; // ms between the last states of the stream
    this._move = null; // { from, to, start, duration } while drawing toward the last state
  }

  /** A state arrived at ``now`` (ms). Every state counts, a still arm's too: its interval is the stream's. */
  arrived(now) {
    const gap = this._lastArrival === null ? Infinity : now - this._lastArrival;
    this._lastArrival = now;
    if (gap > STREAM_GAP_MS) { this._intervals = []; return 0; }
    this._intervals.push(gap);
    if (this._intervals.length > INTERVAL_WINDOW) this._intervals.shift();
    return median(this._intervals);
  }

  /**
   * Move from the drawn values ``from`` to ``to`` (both by joint name), starting at ``now``, over
   * ``duration`` ms (``arrived``'s answer, 0 to draw ``to`` at once). Returns the values to draw at
   * once: ``to`` itself for a duration of 0, else null (``at`` gives them frame by frame).
   */
  toward(from, to, now, duration) {
    if (duration <= 0) { this._move = null; return to; }
    this._move = { from: { ...from }, to: { ...to }, start: now, duration };
    return null;
  }

  /** Whether a move toward the last state is still being drawn. */
  get moving() { return this._move !== null; }

  /** The values to draw at ``now`` while a move lasts (its last answer is its target), else null. */
  at(now) {
    const move = this._move;
    if (!move) return null;
    const u = Math.min(1, Math.max(0, (now - move.start) / move.duration));
    if (u >= 1) this._move = null;
    const values = {};
    for (const [name, target] of Object.entries(move.to)) {
      const start = move.from[name];
      if (start === undefined || u >= 1) { values[name] = target; continue; }
      let delta = target - start;
      if (this.wraps(name)) delta = Math.atan2(Math.sin(delta), Math.cos(delta));
      values[name] = start + delta * u;
    }
    return values;
  }
}
