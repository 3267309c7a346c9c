package caretaker.pax.at;

import caretaker.rosbridge.Ros;
import caretaker.rosbridge.Time;
import caretaker.rosbridge.Topic;
import com.google.gson.JsonObject;
import java.time.Duration;
import java.time.Instant;

/**
 * The AT server's status topic ({@code affordance_template_msgs/msg/ServerStatus}) as the AT
 * plugins ask the bridge for it. Both plugins subscribe with the same settings, and the client
 * makes one server-side subscription of them, so the status crosses the link once.
 *
 * <p>The server publishes at 5 Hz and on every change; the plugins need the latest state, not
 * every message. So the bridge is asked for at most one status per throttle period (the
 * {@code status_throttle} option, default 0.5 s) and to queue one: after an outage the ground
 * gets the newest status, not a backlog that grows with the outage and the link's delay.
 * Compression stays off: a status is ~0.4 KB of JSON, which PNG or CBOR would not shrink enough to
 * pay for their overhead (and this client reads JSON only).
 */
final class AtStatus {
    static final String TYPE = "affordance_template_msgs/msg/ServerStatus";
    /** Default least time between two statuses sent over the link. */
    static final Duration DEFAULT_THROTTLE = Duration.ofMillis(500);

    private AtStatus() {
    }

    /**
     * @param ros the connection
     * @param name the status topic
     * @param throttle least time between two statuses
     * @return the topic, not yet subscribed
     */
    static Topic topic(Ros ros, String name, Duration throttle) {
        return new Topic(ros, name, TYPE, (int) Math.min(Integer.MAX_VALUE, throttle.toMillis()), 1);
    }

    /**
     * @param status a status message
     * @return its habitat timestamp, or null when it has none (or a zero one)
     */
    static Instant stamp(JsonObject status) {
        if (!status.has("stamp")) {
            return null;
        }
        Time time = Time.fromJson(status.get("stamp"));
        return time.isZero() ? null : time.toInstant();
    }
}
