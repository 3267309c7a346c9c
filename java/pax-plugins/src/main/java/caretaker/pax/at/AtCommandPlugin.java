package caretaker.pax.at;

import caretaker.pax.CancelResult;
import caretaker.pax.CommandKey;
import caretaker.pax.CommandPlugin;
import caretaker.pax.CommandResult;
import caretaker.pax.PluginContext;
import caretaker.pax.PluginException;
import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.Header;
import caretaker.rosbridge.LedgerAnswer;
import caretaker.rosbridge.Pose;
import caretaker.rosbridge.RosException;
import caretaker.rosbridge.Service;
import caretaker.sysrep.SysRep;
import com.google.gson.JsonArray;
import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import java.time.Duration;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import java.util.Set;

/**
 * Carries out the six commands of the AT SysRep through the AT server's services (namespace
 * {@code /affordance_template_server} by default).
 *
 * <p>{@code affordance_template} names a type ({@code cdra_filter}) or an instance
 * ({@code cdra_filter:0}). A type is resolved with {@code get_running}: exactly one running
 * instance of it is used; none or several is a failure that lists what runs, never a guess.
 * Commands with an {@code id} argument take it as the instance number when it is 0 or more (a
 * negative id means "resolve from affordance_template"); an id that contradicts an instance name
 * is a failure.
 *
 * <p>Every result is the server's: {@code success: false} from the server or a missing server give a
 * failed {@link CommandResult} with the reason. Every command but the lookup of running instances
 * ({@code get_running}) goes through the command ledger with its key: executed at most once, and
 * UNKNOWN when its outcome cannot be learnt (no answer in time, link lost past its budget).
 *
 * <p>Options: {@code call_timeout} (s, default 10) for quick services, {@code motion_timeout} (s,
 * default 120) for plan and execute.
 */
public final class AtCommandPlugin implements CommandPlugin {
    /** The binding options this plugin reads. */
    public static final Set<String> OPTIONS = Set.of("call_timeout", "motion_timeout");
    private static final List<String> COMMAND_ORDER = List.of("add_affordance_template",
            "delete_affordance_template", "plan_trajectory", "execute_plan", "set_waypoint_pose",
            "set_display_object_pose");
    private static final Set<String> COMMANDS = Set.copyOf(COMMAND_ORDER);

    private final SysRep sysRep;
    private final CommandLedger ledger;
    private final Duration callTimeout;
    private final Duration motionTimeout;
    private final Service addTemplate;
    private final Service deleteTemplate;
    private final Service getRunning;
    private final Service planCommand;
    private final Service executeCommand;
    private final Service setObjectPose;
    private final Service setWaypointPose;
    private final Service halt;

    /**
     * @param context the SysRep (must declare the six commands), connection, namespace, options
     * @throws PluginException the SysRep lacks a command or an option is wrong
     */
    public AtCommandPlugin(PluginContext context) {
        this.sysRep = context.sysRep();
        for (String command : COMMAND_ORDER) {
            if (sysRep.command(command) == null) {
                throw new PluginException(context.options().where() + ": SysRep '" + sysRep.id()
                        + "' has no command '" + command + "'; at_commands serves the AT SysRep"
                        + " (sysrep/affordance_templates.yaml)");
            }
        }
        this.ledger = context.ledger();
        this.callTimeout = context.options().seconds("call_timeout", Duration.ofSeconds(10));
        this.motionTimeout = context.options().seconds("motion_timeout", Duration.ofSeconds(120));
        String msgs = "affordance_template_msgs/srv/";
        addTemplate = new Service(context.ros(), context.resolve("add_template"), msgs + "AddAffordanceTemplate");
        deleteTemplate = new Service(context.ros(), context.resolve("delete_template"),
                msgs + "DeleteAffordanceTemplate");
        getRunning = new Service(context.ros(), context.resolve("get_running"),
                msgs + "GetRunningAffordanceTemplates");
        planCommand = new Service(context.ros(), context.resolve("plan_command"),
                msgs + "AffordanceTemplatePlanCommand");
        executeCommand = new Service(context.ros(), context.resolve("execute_command"),
                msgs + "AffordanceTemplateExecuteCommand");
        setObjectPose = new Service(context.ros(), context.resolve("set_object_pose"), msgs + "SetObjectPose");
        setWaypointPose = new Service(context.ros(), context.resolve("set_waypoint_pose"), msgs + "SetWaypointPose");
        halt = new Service(context.ros(), context.resolve("halt"), null); // its type comes from the ROS graph
    }

    @Override
    public SysRep sysRep() {
        return sysRep;
    }

    @Override
    public Set<String> commands() {
        return COMMANDS;
    }

    @Override
    public CommandResult execute(CommandKey key, String commandId, Map<String, Object> args) {
        Sender sender = new Sender(key, commandId);
        try {
            return switch (commandId) {
                case "add_affordance_template" -> add(sender, args);
                case "delete_affordance_template" -> delete(sender, args);
                case "plan_trajectory" -> plan(sender, args);
                case "execute_plan" -> executePlan(sender, args);
                case "set_waypoint_pose" -> waypointPose(sender, args);
                case "set_display_object_pose" -> displayObjectPose(sender, args);
                default -> throw new PluginException("at_commands does not serve command '" + commandId
                        + "' (commands: " + String.join(", ", new java.util.TreeSet<>(COMMANDS)) + ")");
            };
        } catch (Unresolved e) {
            return CommandResult.failure(e.getMessage());
        } catch (NoReply e) {
            return e.result;
        } catch (RosException e) {
            return CommandResult.failure(commandId + ": " + e.getMessage());
        }
    }

    /**
     * Calls the AT server's halt service, which stops any execution at once (the {@code
     * execute_command} in flight then answers that it was halted). Direct, not through the
     * ledger: a halt is idempotent, so it is called again after a drop, within the link's outage
     * budget ({@link CommandLedger#query}).
     */
    @Override
    public CancelResult cancel(CommandKey key) {
        JsonObject request = new JsonObject();
        request.addProperty("reason", "halt of " + key);
        try {
            JsonObject reply = ledger.query(halt, request, callTimeout).toJsonObject();
            JsonElement success = reply.get("success");
            boolean stopped = success != null && success.isJsonPrimitive() && success.getAsBoolean();
            String said = message(reply);
            return new CancelResult(stopped, said.isEmpty() ? (stopped ? "halted" : "the halt failed") : said);
        } catch (RosException e) {
            return new CancelResult(false, "cannot halt the AT server: " + e.getMessage());
        }
    }

    @Override
    public void close() {
        // Services hold no subscriptions; the connection belongs to the caller.
    }

    private CommandResult add(Sender sender, Map<String, Object> args) {
        String template = (String) args.get("affordance_template");
        if (template.contains(":")) {
            throw new Unresolved("add_affordance_template takes a template type such as 'cdra_filter', not an"
                    + " instance '" + template + "'");
        }
        JsonObject request = new JsonObject();
        request.addProperty("class_type", template);
        request.add("pose", Pose.identity().toStampedJson(new Header(caretaker.rosbridge.Time.now(), "")));
        request.addProperty("hide_waypoints", (Boolean) args.get("hide_waypoints"));
        JsonObject reply = sender.send(addTemplate, request, callTimeout);
        if (!reply.get("success").getAsBoolean()) {
            return failed(reply);
        }
        Map<String, Object> values = new LinkedHashMap<>();
        values.put("id", reply.get("id").getAsLong());
        values.put("instance", reply.get("instance").getAsString());
        return CommandResult.success(message(reply), values);
    }

    private CommandResult delete(Sender sender, Map<String, Object> args) {
        TemplateInstance instance = resolve(args);
        JsonObject request = new JsonObject();
        request.addProperty("class_type", instance.type());
        request.addProperty("id", instance.id());
        return result(sender.send(deleteTemplate, request, callTimeout), instance, Map.of());
    }

    /** The part of plan_command and execute_command requests that names instance and trajectory. */
    private static JsonObject trajectoryRequest(TemplateInstance instance, Map<String, Object> args) {
        JsonObject request = new JsonObject();
        request.addProperty("type", instance.type());
        request.addProperty("id", instance.id());
        request.addProperty("trajectory_name", (String) args.get("trajectory"));
        request.add("end_effectors", new JsonArray());
        return request;
    }

    private CommandResult plan(Sender sender, Map<String, Object> args) {
        TemplateInstance instance = resolve(args);
        JsonObject request = trajectoryRequest(instance, args);
        request.add("steps", new JsonArray());
        request.addProperty("direct", false);
        request.addProperty("backwards", false);
        request.addProperty("execute", false);
        JsonObject reply = sender.send(planCommand, request, motionTimeout);
        JsonObject status = reply.getAsJsonObject("affordance_template_status");
        Map<String, Object> values = new LinkedHashMap<>();
        if (status != null) {
            values.put("plan_status", status.get("plan_status").getAsString());
            values.put("plan_valid", status.get("plan_valid").getAsBoolean());
            endPose(status, values);
        }
        return result(reply, instance, values);
    }

    /**
     * Adds {@code end_pose} ([x, y, z, roll, pitch, yaw]) and {@code end_pose_frame}: where the
     * planned trajectory leaves the end effector, for the operator to check before executing.
     */
    private static void endPose(JsonObject status, Map<String, Object> values) {
        JsonArray infos = status.has("waypoint_info") ? status.getAsJsonArray("waypoint_info") : new JsonArray();
        if (infos.isEmpty() || !infos.get(0).getAsJsonObject().has("waypoint_poses")) {
            return;
        }
        JsonArray poses = infos.get(0).getAsJsonObject().getAsJsonArray("waypoint_poses");
        if (poses.isEmpty()) {
            return;
        }
        JsonObject last = poses.get(poses.size() - 1).getAsJsonObject();
        values.put("end_pose", Pose.fromJson(last.getAsJsonObject("pose")).toXyzRpy());
        values.put("end_pose_frame", last.getAsJsonObject("header").get("frame_id").getAsString());
    }

    private CommandResult executePlan(Sender sender, Map<String, Object> args) {
        TemplateInstance instance = resolve(args);
        JsonObject reply = sender.send(executeCommand, trajectoryRequest(instance, args), motionTimeout);
        JsonObject status = reply.getAsJsonObject("affordance_template_status");
        Map<String, Object> values = new LinkedHashMap<>();
        if (status != null) {
            values.put("execute_status", status.get("execute_status").getAsString());
        }
        return result(reply, instance, values);
    }

    private CommandResult waypointPose(Sender sender, Map<String, Object> args) {
        TemplateInstance instance = resolve(args);
        JsonObject request = new JsonObject();
        request.addProperty("type", instance.type());
        request.addProperty("id", instance.id());
        request.addProperty("trajectory_name", (String) args.get("trajectory"));
        long waypoint = (Long) args.get("waypoint_id");
        if (waypoint < Integer.MIN_VALUE || waypoint > Integer.MAX_VALUE) {
            throw new Unresolved("waypoint_id " + waypoint + " does not fit int32");
        }
        request.addProperty("waypoint_id", waypoint);
        request.addProperty("end_effector", (String) args.get("ee_name"));
        request.add("pose", pose(args).toStampedJson(Header.now((String) args.get("frame_id"))));
        return result(sender.send(setWaypointPose, request, callTimeout), instance, Map.of());
    }

    private CommandResult displayObjectPose(Sender sender, Map<String, Object> args) {
        TemplateInstance instance = resolve(args);
        JsonObject object = new JsonObject();
        object.addProperty("type", instance.type());
        object.addProperty("name", (String) args.get("display_object"));
        object.addProperty("id", instance.id());
        object.add("stamped_pose", pose(args).toStampedJson(Header.now((String) args.get("frame"))));
        JsonArray objects = new JsonArray();
        objects.add(object);
        JsonObject request = new JsonObject();
        request.add("objects", objects);
        return result(sender.send(setObjectPose, request, callTimeout), instance, Map.of());
    }

    private static Pose pose(Map<String, Object> args) {
        return Pose.fromRpy((Double) args.get("x"), (Double) args.get("y"), (Double) args.get("z"),
                (Double) args.get("roll"), (Double) args.get("pitch"), (Double) args.get("yaw"));
    }

    /** Which instance a command means; see the class comment for the rules. */
    private TemplateInstance resolve(Map<String, Object> args) {
        String template = (String) args.get("affordance_template");
        Long id = (Long) args.get("id");
        TemplateInstance named;
        try {
            named = TemplateInstance.parse(template);
        } catch (IllegalArgumentException e) {
            throw new Unresolved(e.getMessage());
        }
        if (named != null) {
            if (id != null && id >= 0 && id != named.id()) {
                throw new Unresolved("affordance_template '" + template + "' and id " + id
                        + " name different instances; give one of them");
            }
            return named;
        }
        if (id != null && id >= 0) {
            if (id > 255) {
                throw new Unresolved("id " + id + " is not a template instance number (0..255)");
            }
            return new TemplateInstance(template, id.intValue());
        }
        List<TemplateInstance> running = running();
        List<TemplateInstance> matching = running.stream().filter(i -> i.type().equals(template)).toList();
        if (matching.size() == 1) {
            return matching.get(0);
        }
        String runningText = running.isEmpty() ? "none" : String.join(", ", running.stream()
                .map(TemplateInstance::toString).toList());
        if (matching.isEmpty()) {
            throw new Unresolved("no running instance of template '" + template + "' (running: " + runningText
                    + "); add it first with add_affordance_template");
        }
        throw new Unresolved("template '" + template + "' is ambiguous: " + matching.size()
                + " instances run (" + runningText + "); name one as '" + template + ":<id>'");
    }

    private List<TemplateInstance> running() {
        JsonObject reply = ledger.query(getRunning, new JsonObject(), callTimeout).toJsonObject();
        if (!reply.has("success")) {
            throw new RosException("reply of " + getRunning.getName() + " has no 'success' field: " + reply);
        }
        if (!reply.get("success").getAsBoolean()) {
            throw new Unresolved("cannot list running templates: " + message(reply));
        }
        List<TemplateInstance> instances = new ArrayList<>();
        for (JsonElement name : reply.getAsJsonArray("templates")) {
            TemplateInstance instance = TemplateInstance.parseOrNull(name.getAsString());
            if (instance != null) {
                instances.add(instance);
            }
        }
        return instances;
    }

    /** Sends one command's state-changing call through the ledger under the command's key. */
    private final class Sender {
        private final CommandKey key;
        private final String commandId;

        Sender(CommandKey key, String commandId) {
            this.key = key;
            this.commandId = commandId;
        }

        /**
         * @return the server's reply, which has a {@code success} field
         * @throws NoReply the outcome is unknown, or the call was never executed
         */
        JsonObject send(Service service, JsonObject request, Duration timeout) {
            LedgerAnswer answer = ledger.execute(key.toString(), service.getName(), service.getType(), request,
                    timeout);
            JsonObject reply = answer.response();
            if (reply == null) {
                throw new NoReply(CommandResult.withoutReply(commandId, answer));
            }
            if (!reply.has("success")) {
                throw new NoReply(CommandResult.unknown(commandId + ": the reply of " + service.getName()
                        + " has no 'success' field, so whether it worked is unknown: " + reply));
            }
            return reply;
        }
    }

    private static CommandResult result(JsonObject reply, TemplateInstance instance, Map<String, Object> extra) {
        if (!reply.get("success").getAsBoolean()) {
            return failed(reply);
        }
        Map<String, Object> values = new LinkedHashMap<>(extra);
        values.put("instance", instance.toString());
        return CommandResult.success(message(reply), values);
    }

    private static CommandResult failed(JsonObject reply) {
        String message = message(reply);
        return CommandResult.failure(message.isEmpty() ? "the AT server reported failure without a message"
                : message);
    }

    private static String message(JsonObject reply) {
        JsonElement message = reply.get("message");
        return message == null || message.isJsonNull() ? "" : message.getAsString();
    }

    /** The system's reply did not come or cannot be read: the result says why. */
    private static final class NoReply extends RuntimeException {
        private static final long serialVersionUID = 1L;
        private final transient CommandResult result;

        NoReply(CommandResult result) {
            super(result.message(), null, false, false);
            this.result = result;
        }
    }

    /** The command cannot name one instance; becomes a failed result, not an exception. */
    private static final class Unresolved extends RuntimeException {
        private static final long serialVersionUID = 1L;

        Unresolved(String message) {
            super(message);
        }
    }
}
