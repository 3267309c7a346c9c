package caretaker.pax.convention;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import caretaker.Repo;
import caretaker.pax.CommandKey;
import caretaker.pax.CommandResult;
import caretaker.pax.PluginContext;
import caretaker.pax.PluginException;
import caretaker.pax.PluginOptions;
import caretaker.pax.TelemetryValue;
import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.LedgerResponder;
import caretaker.rosbridge.LinkOptions;
import caretaker.rosbridge.Ros;
import caretaker.rosbridge.RosOptions;
import caretaker.rosbridge.TestServer;
import caretaker.sysrep.SysRep;
import caretaker.sysrep.SysRepLoader;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.util.HashMap;
import java.util.List;
import java.util.Map;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import org.junit.jupiter.api.AfterEach;
import org.junit.jupiter.api.BeforeEach;
import org.junit.jupiter.api.Test;

/** The naming convention: which services and topics a plain SysRep maps onto, and how replies read. */
class RosConventionPluginTest {
    private TestServer server;
    private Ros ros;
    private CommandLedger ledger;
    private LedgerResponder habitat;

    @BeforeEach
    void start() throws Exception {
        server = new TestServer();
        ros = new Ros(server.uri(), RosOptions.defaults());
        ros.connect();
        ledger = new CommandLedger(ros, LinkOptions.loopback());
    }

    @AfterEach
    void stop() throws Exception {
        ledger.close();
        ros.close();
        server.close();
    }

    private RosConventionPlugin plugin(String sysrep, String namespace, Map<String, Object> options) {
        SysRep sysRep = SysRepLoader.load(Repo.path("sysrep/" + sysrep));
        return new RosConventionPlugin(new PluginContext(sysRep, ros, ledger, namespace,
                new PluginOptions(options, "test")));
    }

    @Test
    void telemetryItemsAreStdMsgsTopicsInTheNamespace() throws Exception {
        try (RosConventionPlugin cdra = plugin("cdra.yaml", "/cdra", Map.of())) {
            Map<String, String> subscribed = new HashMap<>();
            for (int i = 0; i < 4; i++) {
                JsonObject subscribe = server.next("subscribe");
                subscribed.put(subscribe.get("topic").getAsString(), subscribe.get("type").getAsString());
            }
            assertEquals(Map.of("/cdra/filter_locked", "std_msgs/msg/Bool", "/cdra/filter_present", "std_msgs/msg/Bool",
                    "/cdra/installed_filter_id", "std_msgs/msg/String",
                    "/cdra/installed_filter_condition", "std_msgs/msg/String"), subscribed);
            BlockingQueue<TelemetryValue> changes = new LinkedBlockingQueue<>();
            cdra.addListener((sysrep, item, value) -> changes.add(value));
            server.send(JsonParser.parseString("{\"op\":\"publish\",\"topic\":\"/cdra/installed_filter_id\","
                    + "\"msg\":{\"data\":\"CDRA-F-0007\"}}").getAsJsonObject());
            TelemetryValue id = changes.poll(5, TimeUnit.SECONDS);
            assertEquals("CDRA-F-0007", id.value());
            assertFalse(id.stale());
            assertEquals(id, cdra.value("installed_filter_id"));
            assertTrue(cdra.value("filter_locked").stale(), "never received: unknown and stale");
        }
    }

    @Test
    void valuesGoStaleWhenTheConnectionDrops() throws Exception {
        try (RosConventionPlugin cdra = plugin("cdra.yaml", "/cdra", Map.of())) {
            BlockingQueue<TelemetryValue> changes = new LinkedBlockingQueue<>();
            cdra.addListener((sysrep, item, value) -> changes.add(value));
            server.send(JsonParser.parseString("{\"op\":\"publish\",\"topic\":\"/cdra/filter_locked\","
                    + "\"msg\":{\"data\":true}}").getAsJsonObject());
            TelemetryValue fresh = changes.poll(5, TimeUnit.SECONDS);
            assertEquals(true, fresh.value());
            assertFalse(fresh.stale());
            server.dropClient();
            TelemetryValue stale = changes.poll(5, TimeUnit.SECONDS);
            assertTrue(stale.stale());
            assertEquals(true, stale.value(), "the last value is kept, marked stale");
        }
    }

    @Test
    void argumentlessCommandIsATriggerAndRepliesBecomeResults() throws Exception {
        habitat = new LedgerResponder(call -> call.get("op").getAsString().equals("call_service") ? List.of(reply(call,
                "{\"success\":false,\"message\":\"latch jammed\"}")) : List.of());
        server.respond(habitat);
        try (RosConventionPlugin cdra = plugin("cdra.yaml", "/cdra", Map.of())) {
            CommandResult result = cdra.execute(CommandKey.parse("r/1/1"), "lock_filter", Map.of());
            assertFalse(result.success());
            assertEquals("latch jammed", result.message());
            JsonObject call = habitat.next();
            assertEquals("/cdra/lock_filter", call.get("service").getAsString());
            assertEquals("std_srvs/srv/Trigger", call.get("type").getAsString());
            assertThrows(PluginException.class, () -> cdra.execute(CommandKey.parse("r/2/1"), "open_hatch", Map.of()));
        }
    }

    @Test
    void commandArgumentsAreRequestFieldsAndScalarReplyFieldsAreValues() throws Exception {
        habitat = new LedgerResponder(call -> call.get("op").getAsString().equals("call_service") ? List.of(reply(call,
                "{\"success\":true,\"message\":\"saved\",\"path\":\"/tmp/x.png\",\"image\":{\"height\":2}}"))
                : List.of());
        server.respond(habitat);
        try (RosConventionPlugin camera = plugin("camera.yaml", "/camera", Map.of())) {
            CommandResult result = camera.execute(CommandKey.parse("r/3/1"), "capture",
                    Map.of("camera", "scene", "label", "bay"));
            assertTrue(result.success());
            assertEquals(Map.of("path", "/tmp/x.png"), result.values());
            JsonObject call = habitat.next();
            assertEquals("/camera/capture", call.get("service").getAsString());
            assertFalse(call.has("type"), "the type comes from the ROS graph unless service_types names it");
            assertEquals(JsonParser.parseString("{\"camera\":\"scene\",\"label\":\"bay\"}"), call.get("args"));
        }
    }

    @Test
    void optionsMayRenameButOnlyWhatTheSysRepDeclares() {
        try (RosConventionPlugin renamed = plugin("camera.yaml", "/camera",
                Map.of("services", Map.of("capture", "/eva/camera/snap")))) {
            assertEquals(java.util.Set.of("capture"), renamed.commands());
        }
        PluginException typo = assertThrows(PluginException.class, () -> plugin("camera.yaml", "/camera",
                Map.of("services", Map.of("captur", "/x"))));
        assertTrue(typo.getMessage().contains("'captur'"), typo.getMessage());
    }

    private static JsonObject reply(JsonObject call, String values) {
        JsonObject reply = new JsonObject();
        reply.addProperty("op", "service_response");
        reply.add("id", call.get("id"));
        reply.add("service", call.get("service"));
        reply.add("values", JsonParser.parseString(values));
        reply.addProperty("result", true);
        return reply;
    }
}
