package caretaker.pax.at;

import caretaker.pax.BoardTelemetryPlugin;
import caretaker.pax.PluginContext;
import caretaker.pax.TelemetryValue;
import caretaker.rosbridge.JsonValues;
import caretaker.rosbridge.Message;
import caretaker.rosbridge.Time;
import caretaker.rosbridge.Topic;
import caretaker.sysrep.SysRep;
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
 * <p>When no status arrives for {@code stale_after} seconds (option, default 2; the server
 * publishes at 5 Hz or more), every value is marked stale and
 * {@code affordance_template_server_active} reads false — a fresh value, since the absence of the
 * server is itself what we now know. The next status makes everything fresh again; nothing needs
 * restarting.
 */
public final class AtTelemetryPlugin extends BoardTelemetryPlugin {
    /** The binding options this plugin reads. */
    public static final Set<String> OPTIONS = Set.of("stale_after", "status_topic");
    /** The item that reports whether the server is there at all. */
    public static final String SERVER_ACTIVE = "affordance_template_server_active";
    private static final String STATUS_TYPE = "affordance_template_msgs/msg/ServerStatus";

    private final Topic status;
    private final long staleAfterNanos;
    private final ScheduledExecutorService watchdog;
    /** System.nanoTime() of the last status; starts at creation so "never heard" turns stale too. */
    private volatile long lastStatusNanos;
    private volatile boolean serverLost;

    /**
     * @param context the AT SysRep, connection, namespace ({@code /affordance_template_server}),
     *     options {@code stale_after} and {@code status_topic}
     */
    public AtTelemetryPlugin(PluginContext context) {
        super(context.sysRep());
        Duration staleAfter = context.options().seconds("stale_after", Duration.ofSeconds(2));
        this.staleAfterNanos = staleAfter.toNanos();
        this.lastStatusNanos = System.nanoTime();
        this.status = new Topic(context.ros(), context.options().string("status_topic", context.resolve("status")),
                STATUS_TYPE);
        this.watchdog = Executors.newSingleThreadScheduledExecutor(runnable -> {
            Thread thread = new Thread(runnable, "at-telemetry-watchdog " + status.getName());
            thread.setDaemon(true);
            return thread;
        });
        long period = Math.max(TimeUnit.MILLISECONDS.toNanos(20), staleAfterNanos / 5);
        watchdog.scheduleAtFixedRate(this::checkStale, period, period, TimeUnit.NANOSECONDS);
        status.subscribe(this::statusCallback);
    }

    private synchronized void statusCallback(Message message) {
        JsonObject status = message.toJsonObject();
        Instant now = Instant.now();
        Instant stamp = now;
        if (status.has("stamp")) {
            Time time = Time.fromJson(status.get("stamp"));
            stamp = time.isZero() ? now : time.toInstant();
        }
        lastStatusNanos = System.nanoTime();
        serverLost = false;
        for (Telemetry item : sysRep.telemetry()) {
            JsonElement field = status.get(item.id());
            if (field != null && field.isJsonPrimitive()) {
                Object value = item.type().check(item.id(), JsonValues.plain(field));
                board.put(item.id(), new TelemetryValue(value, stamp, false));
            }
        }
    }

    private synchronized void checkStale() {
        if (!serverLost && System.nanoTime() - lastStatusNanos > staleAfterNanos) {
            serverLost = true;
            board.markAllStale();
            if (board.items().contains(SERVER_ACTIVE)) {
                board.put(SERVER_ACTIVE, new TelemetryValue(false, Instant.now(), false));
            }
        }
    }

    @Override
    public void close() {
        watchdog.shutdownNow();
        status.unsubscribe();
    }
}
