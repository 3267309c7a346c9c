package caretaker.pax.convention;

import caretaker.pax.BoardTelemetryPlugin;
import caretaker.pax.CancelResult;
import caretaker.pax.CommandKey;
import caretaker.pax.CommandPlugin;
import caretaker.pax.CommandResult;
import caretaker.pax.PluginContext;
import caretaker.pax.PluginException;
import caretaker.pax.TelemetryValue;
import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.JsonValues;
import caretaker.rosbridge.LedgerAnswer;
import caretaker.rosbridge.Message;
import caretaker.rosbridge.Ros;
import caretaker.rosbridge.RosHandler;
import caretaker.rosbridge.Service;
import caretaker.rosbridge.Topic;
import caretaker.sysrep.Command;
import caretaker.sysrep.SysRep;
import caretaker.sysrep.Telemetry;
import caretaker.sysrep.ValueType;
import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import com.google.gson.JsonPrimitive;
import java.time.Duration;
import java.time.Instant;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.LinkedHashSet;
import java.util.List;
import java.util.Map;
import java.util.Set;
import java.util.concurrent.Executors;
import java.util.concurrent.ScheduledExecutorService;
import java.util.concurrent.TimeUnit;

/**
 * Serves a SysRep by the ROS naming convention, in the binding's namespace {@code <ns>}:
 *
 * <ul>
 *   <li>Command {@code c} calls service {@code <ns>/c}. Without arguments it is a
 *       {@code std_srvs/srv/Trigger}; with arguments, the request has one field per argument, of
 *       the same name (its type comes from the ROS graph, or from option
 *       {@code service_types: {c: pkg/srv/Type}}). The reply's {@code success} and
 *       {@code message} become the result's; every other string, boolean or number field of the
 *       reply becomes a result value (e.g. {@code path} of {@code /camera/capture}). Every
 *       command goes through the command ledger with its key: executed at most once.</li>
 *   <li>Telemetry item {@code t} subscribes to topic {@code <ns>/t}: boolean → {@code std_msgs/msg/Bool},
 *       string → {@code std_msgs/msg/String}, integer → {@code std_msgs/msg/Int64},
 *       real → {@code std_msgs/msg/Float64}; the value is the message's {@code data}. These
 *       messages carry no stamp: a value's timestamp is its arrival less the link's one-way delay
 *       (when it left the habitat), and the bridge queues one message per topic for this client,
 *       so an outage leaves the newest value to send, not a backlog.</li>
 * </ul>
 *
 * <p>Options: {@code services} / {@code topics} (name → ROS name) for the odd name that breaks
 * the convention, {@code service_types}, {@code call_timeout} (s, default 10), {@code stale_after}
 * (s; default: a value goes stale only when the rosbridge connection drops, for topics published
 * only on change).
 */
public final class RosConventionPlugin extends BoardTelemetryPlugin implements CommandPlugin {
    /** The binding options this plugin reads. */
    public static final Set<String> OPTIONS = Set.of("services", "topics", "service_types", "call_timeout",
            "stale_after");
    private static final String TRIGGER = "std_srvs/srv/Trigger";

    private final Duration callTimeout;
    /** The link's expected one-way delay: how old a value at least is when it arrives. */
    private final Duration oneWay;
    private final CommandLedger ledger;
    private final Map<String, Service> services = new LinkedHashMap<>();
    private final List<Topic> topics = new ArrayList<>();
    private final Map<String, Long> lastReceivedNanos = new java.util.concurrent.ConcurrentHashMap<>();
    private final ScheduledExecutorService watchdog;
    private final Ros ros;
    private final RosHandler disconnectHandler;

    /**
     * @param context the SysRep, connection, namespace and options
     * @throws PluginException an option is wrong
     */
    public RosConventionPlugin(PluginContext context) {
        super(context.sysRep());
        this.callTimeout = context.options().seconds("call_timeout", Duration.ofSeconds(10));
        this.ledger = context.ledger();
        this.oneWay = ledger.link().oneWayDelay();
        Map<String, String> serviceNames = context.options().stringMap("services");
        Map<String, String> serviceTypes = context.options().stringMap("service_types");
        Map<String, String> topicNames = context.options().stringMap("topics");
        checkNames(context, "services", serviceNames.keySet(), commandIds());
        checkNames(context, "service_types", serviceTypes.keySet(), commandIds());
        Set<String> itemIds = new LinkedHashSet<>();
        sysRep.telemetry().forEach(t -> itemIds.add(t.id()));
        checkNames(context, "topics", topicNames.keySet(), itemIds);
        for (Command command : sysRep.commands()) {
            String name = serviceNames.getOrDefault(command.id(), context.resolve(command.id()));
            String type = serviceTypes.getOrDefault(command.id(), command.args().isEmpty() ? TRIGGER : null);
            services.put(command.id(), new Service(context.ros(), name, type));
        }
        for (Telemetry item : sysRep.telemetry()) {
            // Queue one: the topics carry state, and after an outage the newest value is what counts.
            Topic topic = new Topic(context.ros(), topicNames.getOrDefault(item.id(), context.resolve(item.id())),
                    messageType(item.type()), 0, 1);
            topic.subscribe(message -> received(item, message));
            topics.add(topic);
        }
        // Values received over a connection that dropped are no longer known to be current.
        this.ros = context.ros();
        this.disconnectHandler = new RosHandler() {
            @Override
            public void handleDisconnection() {
                board.markAllStale();
            }
        };
        ros.addRosHandler(disconnectHandler);
        Duration staleAfter = context.options().seconds("stale_after", null);
        if (staleAfter == null || sysRep.telemetry().isEmpty()) {
            watchdog = null;
        } else {
            watchdog = Executors.newSingleThreadScheduledExecutor(runnable -> {
                Thread thread = new Thread(runnable, "convention-watchdog " + sysRep.id());
                thread.setDaemon(true);
                return thread;
            });
            long period = Math.max(TimeUnit.MILLISECONDS.toNanos(20), staleAfter.toNanos() / 5);
            watchdog.scheduleAtFixedRate(() -> markStale(staleAfter.toNanos()), period, period, TimeUnit.NANOSECONDS);
        }
    }

    private Set<String> commandIds() {
        Set<String> ids = new LinkedHashSet<>();
        sysRep.commands().forEach(c -> ids.add(c.id()));
        return ids;
    }

    private static void checkNames(PluginContext context, String option, Set<String> given, Set<String> known) {
        for (String name : given) {
            if (!known.contains(name)) {
                throw new PluginException(context.options().where() + ": option '" + option + "' names '" + name
                        + "', which SysRep '" + context.sysRep().id() + "' does not declare (declared: "
                        + String.join(", ", known) + ")");
            }
        }
    }

    /**
     * @param type a SysRep value type
     * @return the std_msgs type that carries it by convention
     */
    public static String messageType(ValueType type) {
        return switch (type) {
            case BOOLEAN -> "std_msgs/msg/Bool";
            case STRING -> "std_msgs/msg/String";
            case INTEGER -> "std_msgs/msg/Int64";
            case REAL -> "std_msgs/msg/Float64";
        };
    }

    private synchronized void received(Telemetry item, Message message) {
        JsonElement data = message.toJsonObject().get("data");
        Object value;
        try {
            value = item.type().check(item.id(), JsonValues.plain(data));
        } catch (IllegalArgumentException e) {
            throw new PluginException("topic of " + sysRep.id() + "." + item.id() + " carried a wrong value: "
                    + e.getMessage(), e);
        }
        lastReceivedNanos.put(item.id(), System.nanoTime());
        // std_msgs carry no stamp: the value was current when it left the habitat, a delay ago.
        board.put(item.id(), new TelemetryValue(value, Instant.now().minus(oneWay), false));
    }

    private synchronized void markStale(long staleAfterNanos) {
        long now = System.nanoTime();
        for (Map.Entry<String, Long> entry : lastReceivedNanos.entrySet()) {
            if (now - entry.getValue() > staleAfterNanos) {
                board.put(entry.getKey(), board.get(entry.getKey()).asStale());
            }
        }
    }

    @Override
    public Set<String> commands() {
        return services.keySet();
    }

    @Override
    public CommandResult execute(CommandKey key, String commandId, Map<String, Object> args) {
        Service service = services.get(commandId);
        if (service == null) {
            throw new PluginException("SysRep '" + sysRep.id() + "' has no command '" + commandId + "'");
        }
        JsonObject request = new JsonObject();
        args.forEach((name, value) -> request.add(name, json(value)));
        LedgerAnswer answer = ledger.execute(key.toString(), service.getName(), service.getType(), request,
                callTimeout);
        JsonObject reply = answer.response();
        if (reply == null) {
            return CommandResult.withoutReply(commandId, answer);
        }
        boolean success = !reply.has("success") || reply.get("success").getAsBoolean();
        String message = reply.has("message") ? reply.get("message").getAsString() : "";
        if (!success) {
            return CommandResult.failure(message.isEmpty() ? service.getName() + " reported failure without a message"
                    : message);
        }
        Map<String, Object> values = new LinkedHashMap<>();
        for (Map.Entry<String, JsonElement> field : reply.entrySet()) {
            if (!field.getKey().equals("success") && !field.getKey().equals("message")
                    && field.getValue().isJsonPrimitive()) {
                values.put(field.getKey(), JsonValues.plain(field.getValue()));
            }
        }
        return CommandResult.success(message, values);
    }

    private static JsonElement json(Object value) {
        if (value instanceof Boolean flag) {
            return new JsonPrimitive(flag);
        }
        if (value instanceof Number number) {
            return new JsonPrimitive(number);
        }
        return new JsonPrimitive(String.valueOf(value));
    }

    /** A ROS service call runs to its end: this plugin cannot stop one, and says so. */
    @Override
    public CancelResult cancel(CommandKey key) {
        return new CancelResult(false, sysRep.id() + " commands (ros_convention: ROS service calls) cannot be"
                + " cancelled; " + key + " runs to its end");
    }

    @Override
    public void close() {
        ros.removeRosHandler(disconnectHandler);
        if (watchdog != null) {
            watchdog.shutdownNow();
        }
        topics.forEach(Topic::unsubscribe);
    }
}
