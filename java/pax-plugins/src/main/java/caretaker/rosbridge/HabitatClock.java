package caretaker.rosbridge;

import java.time.Duration;
import java.time.Instant;
import java.util.ArrayDeque;
import java.util.Deque;

/**
 * The habitat's clock as the ground sees it: turns a habitat timestamp into ground time, so that
 * a value's age is measured on one clock even when the two hosts' clocks differ.
 *
 * <p>Each stamped message gives a sample {@code received - stamp} = clock offset + the delay that
 * message met. The smallest sample of the last {@link #WINDOW} is the least-delayed message, so
 * the offset is that minimum minus the link's expected one-way delay (the light time no message
 * beats). Messages held up by a lost segment or an outage give larger samples and are ignored by
 * the minimum; a step of either clock is followed within the window. An error in the stated delay
 * shifts every age by that error (a link slower than stated makes values look younger by the
 * difference), but a stamp is never placed after the moment its message arrived.
 *
 * <p>Thread-safe.
 */
public final class HabitatClock {
    /** How long a sample counts: long enough to catch an undelayed message, short for drift. */
    public static final Duration WINDOW = Duration.ofSeconds(30);

    private final long oneWayNanos;
    private final long windowNanos;
    /** (System.nanoTime() of arrival, sample in ns), samples increasing: a sliding minimum. */
    private final Deque<long[]> samples = new ArrayDeque<>();

    /** @param oneWayDelay the link's expected one-way delay (0 on loopback) */
    public HabitatClock(Duration oneWayDelay) {
        this(oneWayDelay, WINDOW);
    }

    /**
     * @param oneWayDelay the link's expected one-way delay
     * @param window how long a sample counts
     */
    public HabitatClock(Duration oneWayDelay, Duration window) {
        this.oneWayNanos = oneWayDelay.toNanos();
        this.windowNanos = window.toNanos();
    }

    /**
     * Takes one sample.
     *
     * @param stamp the habitat's timestamp of a message
     * @param received when it arrived, on this host's clock
     * @param receivedNanos {@link System#nanoTime()} at arrival
     */
    public synchronized void observe(Instant stamp, Instant received, long receivedNanos) {
        long sample = nanosBetween(stamp, received);
        while (!samples.isEmpty() && samples.peekLast()[1] >= sample) {
            samples.pollLast();
        }
        samples.addLast(new long[] {receivedNanos, sample});
        while (receivedNanos - samples.peekFirst()[0] > windowNanos) {
            samples.pollFirst();
        }
    }

    /** @return whether a sample has been taken */
    public synchronized boolean known() {
        return !samples.isEmpty();
    }

    /** @return ground time minus habitat time; zero before the first sample */
    public synchronized Duration offset() {
        return samples.isEmpty() ? Duration.ZERO : Duration.ofNanos(samples.peekFirst()[1] - oneWayNanos);
    }

    /**
     * @param stamp a habitat timestamp
     * @return the same moment on this host's clock (the stamp itself before the first sample)
     */
    public Instant toGround(Instant stamp) {
        return stamp.plus(offset());
    }

    private static long nanosBetween(Instant from, Instant to) {
        Duration between = Duration.between(from, to);
        try {
            return between.toNanos();
        } catch (ArithmeticException e) { // clocks centuries apart: saturate, the minimum still works
            return between.isNegative() ? Long.MIN_VALUE / 2 : Long.MAX_VALUE / 2;
        }
    }
}
