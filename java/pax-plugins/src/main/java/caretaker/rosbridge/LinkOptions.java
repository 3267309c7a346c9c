package caretaker.rosbridge;

import java.time.Duration;

/**
 * The link between ground and habitat, as a binding states it: what the connection's keepalive
 * and the command ledger's patience are derived from.
 *
 * @param oneWayDelay the expected one-way delay (Gateway: about 1.3 s; loopback: 0)
 * @param outageBudget how long an outage may last before a command in flight is given up as
 *     UNKNOWN (and a silent connection is taken for dead)
 */
public record LinkOptions(Duration oneWayDelay, Duration outageBudget) {
    /** The floor of {@link #pingInterval()}: pings are cheap, not free. */
    private static final Duration MIN_PING_INTERVAL = Duration.ofSeconds(5);
    /** How long a signed login stays valid once it has arrived (the bridge's default age limit). */
    private static final Duration LOGIN_VALIDITY = Duration.ofSeconds(60);

    /** Checks the delay is not negative and the budget positive. */
    public LinkOptions {
        if (oneWayDelay.isNegative()) {
            throw new IllegalArgumentException("one-way delay must not be negative, got " + oneWayDelay);
        }
        if (outageBudget.isNegative() || outageBudget.isZero()) {
            throw new IllegalArgumentException("outage budget must be positive, got " + outageBudget);
        }
    }

    /** @return no delay, a 20 s outage budget (a restart of a habitat process on one host) */
    public static LinkOptions loopback() {
        return new LinkOptions(Duration.ZERO, Duration.ofSeconds(20));
    }

    /** @return the time for a request to go and its answer to come back, without processing */
    public Duration roundTrip() {
        return oneWayDelay.multipliedBy(2);
    }

    /**
     * @return how long a login signed now stays valid: it arrives one delay old, then 60 s (the
     *     Python client's {@code LightTime.login_lifetime}, the same rule)
     */
    public Duration loginValidity() {
        return LOGIN_VALIDITY.plus(oneWayDelay);
    }

    /** @return every 5 s, or every four one-way delays on a longer link */
    public Duration pingInterval() {
        Duration scaled = oneWayDelay.multipliedBy(4);
        return scaled.compareTo(MIN_PING_INTERVAL) > 0 ? scaled : MIN_PING_INTERVAL;
    }

    /**
     * @return silence longer than the outage budget plus a round trip and a ping interval: an
     *     outage the budget allows (traffic held, not reset) never closes the connection
     */
    public Duration pingTimeout() {
        return outageBudget.plus(roundTrip()).plus(pingInterval());
    }
}
