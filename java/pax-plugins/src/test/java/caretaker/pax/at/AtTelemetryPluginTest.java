package caretaker.pax.at;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertNull;
import static org.junit.jupiter.api.Assertions.assertTrue;

import caretaker.pax.PluginContext;
import caretaker.pax.PluginOptions;
import caretaker.pax.TelemetryValue;
import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.LinkOptions;
import caretaker.rosbridge.Ros;
import caretaker.rosbridge.RosOptions;
import caretaker.rosbridge.TestServer;
import caretaker.sysrep.SysRep;
import caretaker.sysrep.SysRepLoader;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.time.Duration;
import java.time.Instant;
import java.util.Map;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import org.junit.jupiter.api.AfterEach;
import org.junit.jupiter.api.BeforeEach;
import org.junit.jupiter.api.Test;

/** The AT telemetry plugin: values from status messages, staleness when they stop, recovery. */
class AtTelemetryPluginTest {
    private TestServer server;
    private Ros ros;
    private AtTelemetryPlugin plugin;
    private final BlockingQueue<String> changes = new LinkedBlockingQueue<>();

    @BeforeEach
    void start() throws Exception {
        server = new TestServer();
        ros = new Ros(server.uri(), RosOptions.defaults());
        ros.connect();
        SysRep sysRep = SysRepLoader.load(caretaker.Repo.path("sysrep/affordance_templates.yaml"));
        plugin = new AtTelemetryPlugin(new PluginContext(sysRep, ros, new CommandLedger(ros, LinkOptions.loopback()),
                "/affordance_template_server",
                new PluginOptions(Map.of("stale_after", 0.3), "test")));
        plugin.addListener((sysrep, item, value) -> changes.add(item + "=" + value.value() + (value.stale() ? " stale"
                : "")));
    }

    @AfterEach
    void stop() throws Exception {
        plugin.close();
        ros.close();
        server.close();
    }

    private void publishStatus(String planStatus) throws Exception {
        JsonObject status = JsonParser.parseString("{\"stamp\":{\"sec\":1700000000,\"nanosec\":5},"
                + "\"robot_name\":\"ur10\",\"robot_active\":false,\"planner_node_active\":true,"
                + "\"affordance_template_server_active\":true,\"execute_status\":\"IDLE\",\"plan_status\":\""
                + planStatus + "\",\"plan_valid\":true,\"running_templates\":[]}").getAsJsonObject();
        JsonObject message = new JsonObject();
        message.addProperty("op", "publish");
        message.addProperty("topic", "/affordance_template_server/status");
        message.add("msg", status);
        server.send(message);
    }

    private void awaitChange(String expected) throws InterruptedException {
        long deadline = System.nanoTime() + TimeUnit.SECONDS.toNanos(5);
        while (System.nanoTime() < deadline) {
            String change = changes.poll(100, TimeUnit.MILLISECONDS);
            if (expected.equals(change)) {
                return;
            }
        }
        throw new AssertionError("no change " + expected + " within 5 s");
    }

    @Test
    void subscribesToTheStatusTopic() throws Exception {
        JsonObject subscribe = server.next("subscribe");
        assertEquals("/affordance_template_server/status", subscribe.get("topic").getAsString());
        assertEquals("affordance_template_msgs/msg/ServerStatus", subscribe.get("type").getAsString());
    }

    @Test
    void valuesFollowStatusThenGoStaleThenRecover() throws Exception {
        server.next("subscribe");
        assertNull(plugin.value("plan_status").value());
        assertTrue(plugin.value("plan_status").stale());
        publishStatus("PLANNED");
        awaitChange("plan_status=PLANNED");
        TelemetryValue plan = plugin.value("plan_status");
        assertFalse(plan.stale());
        assertEquals(Instant.ofEpochSecond(1700000000, 5), plan.timestamp());
        assertEquals(true, plugin.value("planner_node_active").value());
        assertEquals(true, plugin.value("affordance_template_server_active").value());
        // No more status: within stale_after the server reads inactive and the rest is stale.
        awaitChange("affordance_template_server_active=false");
        assertTrue(plugin.value("plan_status").stale());
        assertEquals("PLANNED", plugin.value("plan_status").value());
        assertFalse(plugin.value("affordance_template_server_active").stale());
        publishStatus("IDLE");
        // plan_valid is the last item a status updates: once it is fresh, all are.
        awaitChange("plan_valid=true");
        assertEquals(true, plugin.value("affordance_template_server_active").value());
        assertFalse(plugin.value("plan_status").stale());
        assertEquals("IDLE", plugin.value("plan_status").value());
    }

    @Test
    void unknownItemIsAnErrorNamingTheItems() {
        var error = org.junit.jupiter.api.Assertions.assertThrows(caretaker.pax.PluginException.class,
                () -> plugin.value("battery"));
        assertTrue(error.getMessage().contains("no telemetry item 'battery'"), error.getMessage());
    }
}
