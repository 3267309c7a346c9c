package caretaker.pax.at;

import caretaker.pax.BoardTelemetryPlugin;
import caretaker.pax.PluginContext;
import caretaker.pax.TelemetryValue;
import caretaker.rosbridge.HabitatClock;
import caretaker.rosbridge.JsonValues;
import caretaker.rosbridge.Message;
import caretaker.rosbridge.Ros;
import caretaker.rosbridge.RosHandler;
import caretaker.rosbridge.Time;
import caretaker.rosbridge.Topic;
import caretaker.sysrep.Telemetry;
import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import java.time.Duration;
import java.time.Instant;
import java.util.Set;
import java.util.concurrent.Executors;
import java.util.concurrent.ScheduledExecutorService;
import java.util.concurrent.TimeUnit;

/**
 * Reads the AT SysRep's telemetry from the AT server's status topic
 * ({@code <namespace>/status}, {@code affordance_template_msgs/msg/ServerStatus}): each SysRep
 * item takes the status field of the same name.
 *
 * <p>Times are the habitat's: a value's timestamp is the status's stamp put on this host's clock
 * ({@link HabitatClock}, from the link's expected one-way delay). A value is stale when it is
 * older than {@code stale_after} (option, default 2 s) beyond the link's one-way delay: on a
 * 1.3 s link a status 1.3 s old is as fresh as one can be, one 3.4 s old is stale, and so is one
 * that arrives late behind a lost segment.
 *
 * <p>When statuses stop, every value goes stale. {@code affordance_template_server_active}
 * becomes a fresh {@code false} only when the server's absence is known: the connection is up
 * and carried something sent after the server should have published. While the link is silent
 * (an outage) or down, nothing is known about the server, so it only goes stale. The next status
 * makes everything fresh again; nothing needs restarting.
 *
 * <p>The server publishes at 5 Hz and on every change; the plugin needs the latest state, not every
 * message. So it asks the bridge for at most one status per {@code status_throttle} and to queue
 * one: after an outage the ground gets the newest status, not a backlog that grows with the outage
 * and the link's delay. Compression stays off: a status is ~0.4 KB of JSON, which PNG or CBOR
 * would not shrink enough to pay for their overhead (and the client reads JSON only).
 *
 * <p>Options: {@code stale_after}, {@code status_topic} (default {@code <namespace>/status}),
 * {@code status_throttle} (s, default 0.5).
 */
public final class AtTelemetryPlugin extends BoardTelemetryPlugin {
    /** The binding options this plugin reads. */
    public static final Set<String> OPTIONS = Set.of("stale_after", "status_topic", "status_throttle");
    /** The item that reports whether the server is there at all. */
    public static final String SERVER_ACTIVE = "affordance_template_server_active";
    private static final String STATUS_TYPE = "affordance_template_msgs/msg/ServerStatus";
    private static final Duration DEFAULT_THROTTLE = Duration.ofMillis(500);

    private final Ros ros;
    private final Topic status;
    private final HabitatClock clock;
    private final long oneWayNanos;
    private final long roundTripNanos;
    private final long staleAfterNanos;
    private final ScheduledExecutorService watchdog;
    private final RosHandler connectionWatcher;
    /** System.nanoTime() of the last status's arrival; starts at creation so "never heard" turns stale too. */
    private volatile long lastStatusNanos;
    /** System.nanoTime() at which the last status's values were valid (its stamp on our clock). */
    private volatile long lastValidNanos;
    /** System.nanoTime() of the last (re)connect. */
    private volatile long connectedNanos;
    private volatile boolean stale = true;

    /**
     * @param context the AT SysRep, connection, namespace ({@code /affordance_template_server}),
     *     options {@code stale_after}, {@code status_topic}, {@code status_throttle}
     */
    public AtTelemetryPlugin(PluginContext context) {
        super(context.sysRep());
        this.ros = context.ros();
        Duration oneWay = context.ledger().link().oneWayDelay();
        this.oneWayNanos = oneWay.toNanos();
        this.roundTripNanos = 2 * oneWayNanos;
        this.clock = new HabitatClock(oneWay);
        this.staleAfterNanos = context.options().seconds("stale_after", Duration.ofSeconds(2)).toNanos();
        long now = System.nanoTime();
        this.lastStatusNanos = now;
        this.lastValidNanos = now;
        this.connectedNanos = now;
        long throttle = context.options().seconds("status_throttle", DEFAULT_THROTTLE).toMillis();
        this.status = new Topic(ros, context.options().string("status_topic", context.resolve("status")), STATUS_TYPE,
                (int) Math.min(Integer.MAX_VALUE, throttle), 1);
        this.watchdog = Executors.newSingleThreadScheduledExecutor(runnable -> {
            Thread thread = new Thread(runnable, "at-telemetry-watchdog " + status.getName());
            thread.setDaemon(true);
            return thread;
        });
        this.connectionWatcher = new RosHandler() {
            @Override
            public void handleConnection() {
                connectedNanos = System.nanoTime();
            }
        };
        ros.addRosHandler(connectionWatcher);
        long period = Math.max(TimeUnit.MILLISECONDS.toNanos(20), staleAfterNanos / 5);
        watchdog.scheduleAtFixedRate(this::checkStale, period, period, TimeUnit.NANOSECONDS);
        status.subscribe(this::statusCallback);
    }

    private synchronized void statusCallback(Message message) {
        JsonObject status = message.toJsonObject();
        long nanos = System.nanoTime();
        Instant now = Instant.now();
        Instant stamp = stamp(status);
        Instant valid;
        if (stamp != null) {
            clock.observe(stamp, now, nanos);
            valid = clock.toGround(stamp);
        } else {
            valid = now.minusNanos(oneWayNanos); // no stamp: it left the habitat at least one delay ago
        }
        long ageNanos = Math.max(0, Duration.between(valid, now).toNanos());
        lastStatusNanos = nanos;
        lastValidNanos = nanos - ageNanos;
        stale = tooOld(ageNanos);
        for (Telemetry item : sysRep.telemetry()) {
            JsonElement field = status.get(item.id());
            if (field != null && field.isJsonPrimitive()) {
                Object value = item.type().check(item.id(), JsonValues.plain(field));
                board.put(item.id(), new TelemetryValue(value, valid, stale));
            }
        }
    }

    /** @return the status's habitat timestamp, or null when it has none (or a zero one) */
    private static Instant stamp(JsonObject status) {
        if (!status.has("stamp")) {
            return null;
        }
        Time time = Time.fromJson(status.get("stamp"));
        return time.isZero() ? null : time.toInstant();
    }

    /** Whether a value this old is stale: older than stale_after beyond the light time. */
    private boolean tooOld(long ageNanos) {
        return ageNanos > staleAfterNanos + oneWayNanos;
    }

    private synchronized void checkStale() {
        long now = System.nanoTime();
        if (!tooOld(now - lastValidNanos)) {
            return;
        }
        if (!stale) {
            stale = true;
            board.markAllStale();
        }
        if (board.items().contains(SERVER_ACTIVE) && serverKnownAbsent(now)) {
            TelemetryValue active = board.get(SERVER_ACTIVE);
            if (active.stale() || !Boolean.FALSE.equals(active.value())) {
                board.put(SERVER_ACTIVE, new TelemetryValue(false, Instant.now(), false));
            }
        }
    }

    /**
     * Whether the link carried something sent after the server should have published: frames
     * arrive in order, so a frame heard more than stale_after after the last status (or after a
     * re-subscription could first be answered) means no status was sent meanwhile.
     */
    private boolean serverKnownAbsent(long now) {
        if (!ros.isConnected()) {
            return false;
        }
        long reference = Math.max(lastStatusNanos, connectedNanos + roundTripNanos);
        return ros.lastHeardNanos() - reference > staleAfterNanos;
    }

    @Override
    public void close() {
        watchdog.shutdownNow();
        ros.removeRosHandler(connectionWatcher);
        status.unsubscribe();
    }
}
