package caretaker.pax.at;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import caretaker.pax.CommandKey;
import caretaker.pax.CommandResult;
import caretaker.pax.Outcome;
import caretaker.pax.PluginContext;
import caretaker.pax.PluginException;
import caretaker.pax.PluginOptions;
import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.LedgerResponder;
import caretaker.rosbridge.LinkOptions;
import caretaker.rosbridge.Ros;
import caretaker.rosbridge.RosOptions;
import caretaker.rosbridge.TestServer;
import caretaker.sysrep.Command;
import caretaker.sysrep.SysRep;
import caretaker.sysrep.SysRepLoader;
import com.google.gson.JsonArray;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.time.Duration;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import org.junit.jupiter.api.AfterEach;
import org.junit.jupiter.api.BeforeEach;
import org.junit.jupiter.api.Test;

/**
 * The AT command plugin's mapping of SysRep commands onto AT service requests, its instance
 * resolution and its reporting of the server's outcome. The AT server is played by a responder
 * on {@link TestServer}, behind a {@link LedgerResponder}; the real AT server is exercised by
 * tests/pax.
 */
class AtCommandPluginTest {
    private static final String NS = "/affordance_template_server";

    private TestServer server;
    private Ros ros;
    private CommandLedger ledger;
    private LedgerResponder habitat;
    private int commands;
    private SysRep sysRep;
    private AtCommandPlugin plugin;
    private final List<String> running = new ArrayList<>();
    private volatile JsonObject nextReply = JsonParser.parseString("{\"success\":true,\"message\":\"ok\"}")
            .getAsJsonObject();

    @BeforeEach
    void start() throws Exception {
        server = new TestServer();
        habitat = new LedgerResponder(call -> {
            if (!"call_service".equals(call.get("op").getAsString())) {
                return List.of();
            }
            JsonObject values;
            if (call.get("service").getAsString().equals(NS + "/get_running")) {
                values = new JsonObject();
                values.addProperty("success", true);
                values.addProperty("message", "");
                JsonArray templates = new JsonArray();
                running.forEach(templates::add);
                values.add("templates", templates);
            } else {
                values = nextReply;
            }
            JsonObject reply = new JsonObject();
            reply.addProperty("op", "service_response");
            reply.add("id", call.get("id"));
            reply.add("service", call.get("service"));
            reply.add("values", values);
            reply.addProperty("result", true);
            return List.of(reply);
        });
        server.respond(habitat);
        ros = new Ros(server.uri(), RosOptions.defaults().withTimeout(Duration.ofSeconds(5)));
        ros.connect();
        ledger = new CommandLedger(ros, LinkOptions.loopback());
        sysRep = SysRepLoader.load(caretaker.Repo.path("sysrep/affordance_templates.yaml"));
        plugin = new AtCommandPlugin(new PluginContext(sysRep, ros, ledger, NS, new PluginOptions(Map.of(), "test")));
    }

    @AfterEach
    void stop() throws Exception {
        plugin.close();
        ledger.close();
        ros.close();
        server.close();
    }

    private CommandResult run(String command, Map<String, ?> args) {
        Command declared = sysRep.command(command);
        return plugin.execute(new CommandKey("test-run", "1." + ++commands, 1), command,
                declared.checkArguments(args));
    }

    /** The next call of {@code service} the ledger made for the plugin. */
    private JsonObject call(String service) throws InterruptedException {
        while (true) {
            JsonObject message = habitat.next();
            if (message.get("service").getAsString().equals(NS + "/" + service)) {
                return message.getAsJsonObject("args");
            }
        }
    }

    @Test
    void servesTheSixCommands() {
        assertEquals(sysRep.commands().stream().map(Command::id).collect(java.util.stream.Collectors.toSet()),
                plugin.commands());
    }

    @Test
    void addTemplateTakesATypeAndReturnsTheInstance() throws Exception {
        nextReply = JsonParser.parseString("{\"success\":true,\"message\":\"added\",\"id\":2,"
                + "\"instance\":\"cdra_filter:2\"}").getAsJsonObject();
        CommandResult result = run("add_affordance_template", Map.of("affordance_template", "cdra_filter",
                "hide_waypoints", true));
        assertTrue(result.success());
        assertEquals(Map.of("id", 2L, "instance", "cdra_filter:2"), result.values());
        JsonObject args = call("add_template");
        assertEquals("cdra_filter", args.get("class_type").getAsString());
        assertTrue(args.get("hide_waypoints").getAsBoolean());
        assertEquals("", args.getAsJsonObject("pose").getAsJsonObject("header").get("frame_id").getAsString());

        CommandResult instance = run("add_affordance_template", Map.of("affordance_template", "cdra_filter:0",
                "hide_waypoints", false));
        assertFalse(instance.success());
        assertTrue(instance.message().contains("template type"), instance.message());
    }

    @Test
    void planWithATypeUsesItsOnlyRunningInstance() throws Exception {
        running.addAll(List.of("cdra_filter:3", "hatch:0"));
        nextReply = JsonParser.parseString("{\"success\":true,\"message\":\"planned\",\"affordance_template_status\":"
                + "{\"plan_status\":\"PLANNED\",\"plan_valid\":true,\"execute_status\":\"IDLE\",\"waypoint_info\":"
                + "[{\"waypoint_poses\":[{\"header\":{\"frame_id\":\"base_link\"},\"pose\":{\"position\":{\"x\":1.0}}},"
                + "{\"header\":{\"frame_id\":\"base_link\"},\"pose\":{\"position\":{\"x\":0.5,\"y\":0.25,\"z\":0.75},"
                + "\"orientation\":{\"z\":0.7071067811865476,\"w\":0.7071067811865476}}}]}]}}").getAsJsonObject();
        CommandResult result = run("plan_trajectory", Map.of("affordance_template", "cdra_filter",
                "trajectory", "remove"));
        assertTrue(result.success(), result.message());
        assertEquals("planned", result.message());
        assertEquals("PLANNED", result.values().get("plan_status"));
        assertEquals(true, result.values().get("plan_valid"));
        List<?> end = (List<?>) result.values().get("end_pose");
        assertEquals(List.of(0.5, 0.25, 0.75), end.subList(0, 3));
        assertEquals(Math.PI / 2, (Double) end.get(5), 1e-9);
        assertEquals("base_link", result.values().get("end_pose_frame"));
        assertEquals("cdra_filter:3", result.values().get("instance"));
        JsonObject args = call("plan_command");
        assertEquals("cdra_filter", args.get("type").getAsString());
        assertEquals(3, args.get("id").getAsInt());
        assertEquals("remove", args.get("trajectory_name").getAsString());
        assertFalse(args.get("execute").getAsBoolean());
    }

    @Test
    void ambiguousOrMissingTemplateIsAFailureNeverAGuess() {
        running.addAll(List.of("cdra_filter:0", "cdra_filter:1"));
        CommandResult ambiguous = run("execute_plan", Map.of("affordance_template", "cdra_filter",
                "trajectory", "remove"));
        assertFalse(ambiguous.success());
        assertTrue(ambiguous.message().contains("ambiguous") && ambiguous.message().contains("cdra_filter:1"),
                ambiguous.message());
        CommandResult missing = run("execute_plan", Map.of("affordance_template", "hatch", "trajectory", "open"));
        assertFalse(missing.success());
        assertTrue(missing.message().contains("no running instance of template 'hatch'"), missing.message());
        CommandResult conflicting = run("delete_affordance_template", Map.of("affordance_template", "cdra_filter:0",
                "id", 1));
        assertFalse(conflicting.success());
        assertTrue(conflicting.message().contains("different instances"), conflicting.message());
    }

    @Test
    void serverFailureIsReportedWithItsMessage() {
        nextReply = JsonParser.parseString("{\"success\":false,\"message\":\"no IK solution for waypoint 2\","
                + "\"affordance_template_status\":{\"plan_status\":\"PLAN_FAILED\",\"plan_valid\":false}}")
                .getAsJsonObject();
        CommandResult result = run("plan_trajectory", Map.of("affordance_template", "cdra_filter:0",
                "trajectory", "remove"));
        assertFalse(result.success());
        assertEquals("no IK solution for waypoint 2", result.message());
    }

    @Test
    void missingServerIsAFailureNotAHang() throws Exception {
        server.respond(new LedgerResponder(call -> {
            JsonObject reply = new JsonObject();
            reply.addProperty("op", "service_response");
            reply.add("id", call.get("id"));
            reply.add("service", call.get("service"));
            reply.addProperty("values", "Service " + call.get("service").getAsString() + " does not exist");
            reply.addProperty("result", false);
            return List.of(reply);
        }));
        CommandResult result = run("execute_plan", Map.of("affordance_template", "cdra_filter:0",
                "trajectory", "remove"));
        assertEquals(Outcome.FAILED, result.outcome());
        assertTrue(result.message().contains("not executed") && result.message().contains("does not exist"),
                result.message());
    }

    @Test
    void commandsCarryTheirKeyAndAnUnknownOutcomeStaysUnknown() throws Exception {
        List<JsonObject> executes = new java.util.concurrent.CopyOnWriteArrayList<>();
        server.respond(call -> {
            JsonObject values = new JsonObject();
            values.addProperty("epoch", "e1");
            if (call.get("service").getAsString().equals(CommandLedger.EXECUTE_SERVICE)) {
                executes.add(call.getAsJsonObject("args"));
                values.addProperty("state", "UNKNOWN");
                values.addProperty("message", "the server of execute_command went away before answering");
            } else {
                values.addProperty("state", "NOT_FOUND");
            }
            JsonObject reply = new JsonObject();
            reply.addProperty("op", "service_response");
            reply.add("id", call.get("id"));
            reply.add("service", call.get("service"));
            reply.add("values", values);
            reply.addProperty("result", true);
            return List.of(reply);
        });
        CommandResult result = plugin.execute(CommandKey.parse("run-7/4.2/3"), "execute_plan",
                sysRep.command("execute_plan").checkArguments(Map.of("affordance_template", "cdra_filter:0",
                        "trajectory", "remove")));
        assertEquals(Outcome.UNKNOWN, result.outcome());
        assertFalse(result.success());
        assertTrue(result.message().contains("outcome unknown") && result.message().contains("went away"),
                result.message());
        assertEquals(1, executes.size());
        JsonObject sent = executes.get(0);
        assertEquals("run-7/4.2/3", sent.get("command_key").getAsString());
        assertEquals("", sent.get("epoch").getAsString());
        assertEquals(NS + "/execute_command", sent.get("service").getAsString());
        assertEquals("affordance_template_msgs/srv/AffordanceTemplateExecuteCommand", sent.get("type").getAsString());
        assertEquals(180.0, sent.get("timeout").getAsDouble() + 60.0, 1e-9); // motion_timeout, default 120 s
        assertEquals("remove", JsonParser.parseString(sent.get("request_json").getAsString()).getAsJsonObject()
                .get("trajectory_name").getAsString());
    }

    @Test
    void displayObjectPoseBecomesAPoseStampedInTheFrame() throws Exception {
        Map<String, Object> args = new LinkedHashMap<>();
        args.put("affordance_template", "cdra_filter");
        args.put("id", 0);
        args.put("display_object", "filter");
        args.put("frame", "cabinet_slot");
        args.put("x", 0.1);
        args.put("y", 0.2);
        args.put("z", "0.3");
        args.put("roll", 0.0);
        args.put("pitch", 0.0);
        args.put("yaw", Math.PI);
        assertTrue(run("set_display_object_pose", args).success());
        JsonObject object = call("set_object_pose").getAsJsonArray("objects").get(0).getAsJsonObject();
        assertEquals("cdra_filter", object.get("type").getAsString());
        assertEquals("filter", object.get("name").getAsString());
        assertEquals(0, object.get("id").getAsInt());
        JsonObject stamped = object.getAsJsonObject("stamped_pose");
        assertEquals("cabinet_slot", stamped.getAsJsonObject("header").get("frame_id").getAsString());
        assertTrue(stamped.getAsJsonObject("header").getAsJsonObject("stamp").has("nanosec"));
        JsonObject pose = stamped.getAsJsonObject("pose");
        assertEquals(0.3, pose.getAsJsonObject("position").get("z").getAsDouble(), 1e-12);
        assertEquals(1.0, pose.getAsJsonObject("orientation").get("z").getAsDouble(), 1e-12);
        assertEquals(0.0, pose.getAsJsonObject("orientation").get("w").getAsDouble(), 1e-12);
    }

    @Test
    void waypointPoseNamesTrajectoryWaypointAndEndEffector() throws Exception {
        Map<String, Object> args = new LinkedHashMap<>();
        args.put("affordance_template", "cdra_filter:1");
        args.put("id", -1);
        args.put("trajectory", "remove");
        args.put("waypoint_id", 2);
        args.put("ee_name", "gripper");
        for (String axis : List.of("x", "y", "z", "roll", "pitch", "yaw")) {
            args.put(axis, 0.0);
        }
        args.put("frame_id", "");
        assertTrue(run("set_waypoint_pose", args).success());
        JsonObject request = call("set_waypoint_pose");
        assertEquals(1, request.get("id").getAsInt());
        assertEquals(2, request.get("waypoint_id").getAsInt());
        assertEquals("gripper", request.get("end_effector").getAsString());
        assertEquals(1.0, request.getAsJsonObject("pose").getAsJsonObject("pose").getAsJsonObject("orientation")
                .get("w").getAsDouble(), 1e-12);
    }

    @Test
    void wrongSysRepOrOptionIsRefused() {
        SysRep cdra = SysRepLoader.load(caretaker.Repo.path("sysrep/cdra.yaml"));
        PluginException wrongSysRep = assertThrows(PluginException.class, () -> new AtCommandPlugin(
                new PluginContext(cdra, ros, ledger, NS, new PluginOptions(Map.of(), "iva.yaml: systems[1]"))));
        assertTrue(wrongSysRep.getMessage().contains("has no command 'add_affordance_template'"));
        PluginException typo = assertThrows(PluginException.class, () -> caretaker.binding.PluginKind.checkOptions(
                List.of("at_commands", "at_telemetry"), new PluginOptions(Map.of("call_timout", 1), "iva.yaml")));
        assertTrue(typo.getMessage().contains("no option 'call_timout'"), typo.getMessage());
    }
}
