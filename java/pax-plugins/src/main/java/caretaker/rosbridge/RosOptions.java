package caretaker.rosbridge;

import java.time.Duration;
import javax.net.ssl.SSLContext;

/**
 * How a {@link Ros} connection behaves.
 *
 * @param timeout the limit of every blocking step: connecting, sending, and the default for
 *     service calls
 * @param reconnectMin the first delay before reconnecting after a drop; it doubles per failure
 * @param reconnectMax the largest delay between reconnect attempts
 * @param pingInterval how often a WebSocket ping is sent while connected
 * @param pingTimeout how long the server may stay silent (no frame, no pong) before the connection
 *     is taken for dead, closed and reconnected; longer than any outage the link should ride out
 * @param auth the {@code auth} message sent first on every (re)connect, or null for none
 * @param tls the TLS context for {@code wss://} (whom to trust), or null for the JDK's default
 */
public record RosOptions(Duration timeout, Duration reconnectMin, Duration reconnectMax, Duration pingInterval,
        Duration pingTimeout, RosAuth auth, SSLContext tls) {
    /** Checks the durations are positive and ordered. */
    public RosOptions {
        positive("timeout", timeout);
        positive("reconnectMin", reconnectMin);
        positive("pingInterval", pingInterval);
        if (reconnectMax.compareTo(reconnectMin) < 0) {
            throw new IllegalArgumentException("need reconnectMin <= reconnectMax, got " + reconnectMin + " and "
                    + reconnectMax);
        }
        if (pingTimeout.compareTo(pingInterval) <= 0) {
            throw new IllegalArgumentException("pingTimeout must be longer than pingInterval, got " + pingTimeout
                    + " and " + pingInterval);
        }
    }

    /**
     * Options without keepalive tuning, authentication or TLS settings (loopback defaults for those).
     *
     * @param timeout the limit of every blocking step
     * @param reconnectMin the first reconnect delay
     * @param reconnectMax the largest reconnect delay
     */
    public RosOptions(Duration timeout, Duration reconnectMin, Duration reconnectMax) {
        this(timeout, reconnectMin, reconnectMax, LinkOptions.loopback().pingInterval(),
                LinkOptions.loopback().pingTimeout(), null, null);
    }

    private static void positive(String name, Duration value) {
        if (value.isNegative() || value.isZero()) {
            throw new IllegalArgumentException(name + " must be positive, got " + value);
        }
    }

    /** @return 10 s timeout; reconnect after 0.1 s, backing off to 2 s; keepalive for loopback */
    public static RosOptions defaults() {
        return new RosOptions(Duration.ofSeconds(10), Duration.ofMillis(100), Duration.ofSeconds(2));
    }

    /**
     * @param newTimeout the timeout to use
     * @return these options with another timeout
     */
    public RosOptions withTimeout(Duration newTimeout) {
        return new RosOptions(newTimeout, reconnectMin, reconnectMax, pingInterval, pingTimeout, auth, tls);
    }

    /**
     * @param link the link the connection crosses
     * @return these options with keepalive that rides out the link's delay and outage budget, and
     *     a timeout that covers four round trips on it: opening a {@code wss://} connection takes
     *     three (TCP, TLS, the WebSocket upgrade) and the authentication check one more
     */
    public RosOptions withLink(LinkOptions link) {
        return new RosOptions(timeout.plus(link.roundTrip().multipliedBy(4)), reconnectMin, reconnectMax,
                link.pingInterval(), link.pingTimeout(), auth, tls);
    }

    /**
     * @param newAuth the auth message to send first on every (re)connect, or null
     * @return these options with that authentication
     */
    public RosOptions withAuth(RosAuth newAuth) {
        return new RosOptions(timeout, reconnectMin, reconnectMax, pingInterval, pingTimeout, newAuth, tls);
    }

    /**
     * @param newTls the TLS context for wss:// (see {@link CaTrust#trusting}), or null
     * @return these options with that TLS context
     */
    public RosOptions withTls(SSLContext newTls) {
        return new RosOptions(timeout, reconnectMin, reconnectMax, pingInterval, pingTimeout, auth, newTls);
    }
}
