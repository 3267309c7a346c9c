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
        plugin = plugin(LinkOptions.loopback());
    }

    private AtTelemetryPlugin plugin(LinkOptions link) {
        SysRep sysRep = SysRepLoader.load(caretaker.Repo.path("sysrep/affordance_templates.yaml"));
        AtTelemetryPlugin made = new AtTelemetryPlugin(new PluginContext(sysRep, ros, new CommandLedger(ros, link),
                "/affordance_template_server", new PluginOptions(Map.of("stale_after", 0.3), "test")));
        made.addListener((sysrep, item, value) -> changes.add(item + "=" + value.value() + (value.stale() ? " stale"
                : "")));
        return made;
    }

    @AfterEach
    void stop() throws Exception {
        plugin.close();
        ros.close();
        server.close();
    }

    private void publishStatus(String planStatus) throws Exception {
        publishStatus(planStatus, Instant.now().minus(Duration.ofDays(1000))); // a habitat clock years behind
    }

    private void publishStatus(String planStatus, Instant stamp) throws Exception {
        JsonObject status = JsonParser.parseString("{\"stamp\":{\"sec\":" + stamp.getEpochSecond() + ",\"nanosec\":"
                + stamp.getNano() + "},"
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

    /** Waits until every one of {@code expected} was seen, in any order. */
    private void awaitChanges(java.util.Set<String> expected) throws InterruptedException {
        java.util.Set<String> missing = new java.util.HashSet<>(expected);
        long deadline = System.nanoTime() + TimeUnit.SECONDS.toNanos(5);
        while (!missing.isEmpty() && System.nanoTime() < deadline) {
            String change = changes.poll(100, TimeUnit.MILLISECONDS);
            missing.remove(change);
        }
        if (!missing.isEmpty()) {
            throw new AssertionError("no change " + missing + " within 5 s");
        }
    }

    @Test
    void subscribesToTheLatestStatusAtMostTwiceASecond() throws Exception {
        JsonObject subscribe = server.next("subscribe");
        assertEquals("/affordance_template_server/status", subscribe.get("topic").getAsString());
        assertEquals("affordance_template_msgs/msg/ServerStatus", subscribe.get("type").getAsString());
        assertEquals(500, subscribe.get("throttle_rate").getAsInt());
        assertEquals(1, subscribe.get("queue_length").getAsInt(), "after an outage the newest, not a backlog");
    }

    @Test
    void aValueAsOldAsTheLinkDelayIsFreshAndOneLateBehindAStallIsStale() throws Exception {
        plugin.close();
        plugin = plugin(new LinkOptions(Duration.ofMillis(1300), Duration.ofSeconds(60)));
        changes.clear();
        Instant before = Instant.now();
        publishStatus("PLANNED", before.minusMillis(1300)); // as old as the light time: fresh
        awaitChange("plan_status=PLANNED");
        TelemetryValue fresh = plugin.value("plan_status");
        assertFalse(fresh.stale());
        assertFalse(fresh.timestamp().isAfter(Instant.now().minusMillis(1300)));
        assertFalse(fresh.timestamp().isBefore(before.minusMillis(1300)));
        publishStatus("PLANNING", Instant.now().minusMillis(3400)); // 2.1 s late behind a lost segment
        awaitChange("plan_status=PLANNING stale");
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
        // the stamp put on this host's clock: a loopback status is as old as it took to arrive
        assertTrue(Duration.between(plan.timestamp(), Instant.now()).abs().compareTo(Duration.ofSeconds(1)) < 0,
                plan.timestamp().toString());
        assertEquals(true, plugin.value("planner_node_active").value());
        assertEquals(true, plugin.value("affordance_template_server_active").value());
        // No more status: everything goes stale; whether the server is gone is not known yet.
        awaitChanges(java.util.Set.of("affordance_template_server_active=true stale", "plan_status=PLANNED stale"));
        assertEquals("PLANNED", plugin.value("plan_status").value());
        // The link carries something sent after the server should have published: it is gone.
        JsonObject other = new JsonObject();
        other.addProperty("op", "publish");
        other.addProperty("topic", "/elsewhere");
        other.add("msg", new JsonObject());
        server.send(other);
        awaitChange("affordance_template_server_active=false");
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
