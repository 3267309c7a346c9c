package caretaker.rosbridge;

import java.time.Duration;

/**
 * How a {@link Ros} connection behaves.
 *
 * @param timeout the limit of every blocking step: connecting, sending, and the default for
 *     service calls
 * @param reconnectMin the first delay before reconnecting after a drop; it doubles per failure
 * @param reconnectMax the largest delay between reconnect attempts
 */
public record RosOptions(Duration timeout, Duration reconnectMin, Duration reconnectMax) {
    /** Checks the durations are positive and ordered. */
    public RosOptions {
        if (timeout.isNegative() || timeout.isZero()) {
            throw new IllegalArgumentException("timeout must be positive, got " + timeout);
        }
        if (reconnectMin.isNegative() || reconnectMin.isZero() || reconnectMax.compareTo(reconnectMin) < 0) {
            throw new IllegalArgumentException("need 0 < reconnectMin <= reconnectMax, got " + reconnectMin
                    + " and " + reconnectMax);
        }
    }

    /** @return 10 s timeout; reconnect after 0.1 s, backing off to 2 s */
    public static RosOptions defaults() {
        return new RosOptions(Duration.ofSeconds(10), Duration.ofMillis(100), Duration.ofSeconds(2));
    }

    /**
     * @param newTimeout the timeout to use
     * @return these options with another timeout
     */
    public RosOptions withTimeout(Duration newTimeout) {
        return new RosOptions(newTimeout, reconnectMin, reconnectMax);
    }
}
