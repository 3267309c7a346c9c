package caretaker.binding;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import caretaker.pax.CancelResult;
import caretaker.pax.CommandKey;
import caretaker.pax.CommandResult;
import caretaker.pax.Outcome;
import caretaker.pax.PluginException;
import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.LedgerMissingException;
import caretaker.rosbridge.LedgerResponder;
import caretaker.rosbridge.RosException;
import caretaker.rosbridge.TestServer;
import caretaker.sysrep.SysRep;
import caretaker.Repo;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.io.IOException;
import java.net.ServerSocket;
import java.net.URI;
import java.nio.file.Files;
import java.nio.file.Path;
import java.util.List;
import java.util.Map;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.CompletableFuture;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import org.junit.jupiter.api.Test;
import org.junit.jupiter.api.io.TempDir;

/** Binding files and the Java host: what an integrator uses without Python. */
class PaxHostTest {
    private static final Path BINDINGS = Repo.path("sysrep/bindings");

    @Test
    void theSameAtSysRepIsBoundOnBothRobots() {
        Binding iva = BindingLoader.load(BINDINGS.resolve("iva.yaml"), null);
        Binding eva = BindingLoader.load(BINDINGS.resolve("eva.yaml"), null);
        assertEquals("iva", iva.robot());
        assertEquals("eva", eva.robot());
        SystemBinding ivaAt = iva.systems().get(0);
        SystemBinding evaAt = eva.systems().get(0);
        assertEquals(ivaAt.sysRep(), evaAt.sysRep());
        assertEquals(List.of("at_commands", "at_telemetry"), ivaAt.plugins());
        assertFalse(ivaAt.rosbridge().equals(evaAt.rosbridge()));
        assertEquals(List.of("affordance_templates", "cdra", "gripper", "camera", "perception"), iva.systems().stream().map(s -> s.sysRep().id()).toList());
        assertEquals(List.of("affordance_templates", "camera", "perception"), eva.systems().stream().map(s -> s.sysRep().id()).toList());
        URI test = URI.create("ws://127.0.0.1:1234");
        assertTrue(BindingLoader.load(BINDINGS.resolve("iva.yaml"), test).systems().stream()
                .allMatch(s -> s.rosbridge().equals(test)));
    }

    @Test
    void badBindingsSayWhatToFix(@TempDir Path dir) throws IOException {
        Path file = dir.resolve("bad.yaml");
        Files.writeString(file, "robot: x\nrosbridge: ws://127.0.0.1:1\nsystems:\n- sysrep: "
                + Repo.path("sysrep/cdra.yaml") + "\n  plugins: [ros_convention]\n  namspace: /c\n");
        BindingException key = assertThrows(BindingException.class, () -> BindingLoader.load(file, null));
        assertTrue(key.getMessage().contains("systems[0]: unknown key 'namspace'"), key.getMessage());
        Files.writeString(file, "robot: x\nrosbridge: ws://127.0.0.1:1\nsystems:\n- sysrep: "
                + Repo.path("sysrep/affordance_templates.yaml") + "\n  plugins: [at_commands, at_telemetry]\n"
                + "  options: {stale_afte: 1}\n");
        BindingException option = assertThrows(BindingException.class, () -> BindingLoader.load(file, null));
        assertTrue(option.getMessage().contains("no option 'stale_afte'"), option.getMessage());
        Files.writeString(file, "robot: x\nrosbridge: http://h\nsystems: []\n");
        assertTrue(assertThrows(BindingException.class, () -> BindingLoader.load(file, null)).getMessage()
                .contains("not a rosbridge URL"));
    }

    @Test
    void unreachableRosbridgeIsAClearError() throws IOException {
        int port;
        try (ServerSocket free = new ServerSocket(0)) {
            port = free.getLocalPort();
        }
        RosException error = assertThrows(RosException.class, () -> PaxHost.open(BINDINGS.resolve("iva.yaml"),
                URI.create("ws://127.0.0.1:" + port)));
        assertTrue(error.getMessage().contains("caretaker bridge"), error.getMessage());
        assertTrue(error.getMessage().contains("iva.yaml"), error.getMessage());
    }

    @Test
    void aBindingThatStatesALinkRefusesAHabitatWithoutALedger(@TempDir Path dir) throws Exception {
        Path file = dir.resolve("ground.yaml");
        Files.writeString(file, "robot: iva\nrosbridge: ws://127.0.0.1:1\nlink: {one_way_delay: 0.1, outage_budget: 5}\n"
                + "systems:\n- sysrep: " + Repo.path("sysrep/cdra.yaml") + "\n  plugins: [ros_convention]\n"
                + "  namespace: /cdra\n");
        assertTrue(BindingLoader.load(file, null).linkStated());
        assertEquals("", BindingLoader.load(file, null).ledgerNamespace());
        Path namespaced = dir.resolve("namespaced.yaml");
        Files.writeString(namespaced, Files.readString(file) + "ledger_namespace: /bench\n");
        assertEquals("/bench", BindingLoader.load(namespaced, null).ledgerNamespace());
        Files.writeString(namespaced, Files.readString(file) + "ledger_namespace: bench/\n");
        assertTrue(assertThrows(BindingException.class, () -> BindingLoader.load(namespaced, null)).getMessage()
                .contains("namespaced.yaml:8: ledger_namespace: must be a ROS namespace like /iva"));
        assertFalse(BindingLoader.load(BINDINGS.resolve("iva.yaml"), null).linkStated());
        try (TestServer server = new TestServer()) {
            server.respond(call -> {
                if (!"call_service".equals(call.get("op").getAsString())) {
                    return List.of();
                }
                JsonObject reply = JsonParser.parseString("{\"op\":\"service_response\",\"result\":false}")
                        .getAsJsonObject();
                reply.add("id", call.get("id"));
                reply.add("service", call.get("service"));
                reply.addProperty("values", "Service " + call.get("service").getAsString() + " does not exist");
                return List.of(reply);
            });
            LedgerMissingException error = assertThrows(LedgerMissingException.class, () -> PaxHost.open(file,
                    server.uri()));
            assertTrue(error.getMessage().startsWith(file + ": systems[0]: this binding states a link: no command"
                    + " ledger at " + server.uri()), error.getMessage());
        }
    }

    @Test
    void trafficIsCountedPerConnection() throws Exception {
        try (TestServer server = new TestServer()) {
            server.respond(new LedgerResponder(call -> List.of()));
            try (PaxHost host = PaxHost.open(BINDINGS.resolve("iva.yaml"), server.uri())) {
                List<caretaker.rosbridge.Traffic> traffic = host.traffic();
                assertEquals(1, traffic.size(), "both systems share one connection");
                assertEquals(server.uri(), traffic.get(0).rosbridge());
                assertTrue(traffic.get(0).bytesUp() > 0 && traffic.get(0).bytesDown() > 0, traffic.toString());
            }
        }
    }

    @Test
    void conventionCommandsAndArgumentChecksThroughTheHost() throws Exception {
        try (TestServer server = new TestServer()) {
            LedgerResponder habitat = new LedgerResponder(call -> {
                if (!"call_service".equals(call.get("op").getAsString())) {
                    return List.of();
                }
                JsonObject reply = JsonParser.parseString("{\"op\":\"service_response\",\"result\":true,"
                        + "\"values\":{\"success\":true,\"message\":\"unlocked\"}}").getAsJsonObject();
                reply.add("id", call.get("id"));
                reply.add("service", call.get("service"));
                return List.of(reply);
            });
            server.respond(habitat);
            try (PaxHost host = PaxHost.open(BINDINGS.resolve("iva.yaml"), server.uri())) {
                assertEquals(List.of("affordance_templates", "cdra", "gripper", "camera", "perception"), host.sysReps().stream().map(SysRep::id).toList());
                CommandResult result = host.execute(CommandKey.parse("run/1.1/1"), "cdra", "unlock_filter", Map.of());
                assertTrue(result.success());
                assertEquals("unlocked", result.message());
                JsonObject call = habitat.next();
                assertEquals("/cdra/unlock_filter", call.get("service").getAsString());
                assertEquals("std_srvs/srv/Trigger", call.get("type").getAsString());
                PluginException badArg = assertThrows(PluginException.class, () -> host.execute(
                        CommandKey.parse("run/1.2/1"), "affordance_templates", "plan_trajectory", Map.of("affordance_template", "x")));
                assertTrue(badArg.getMessage().contains("missing argument 'trajectory'"), badArg.getMessage());
                assertTrue(assertThrows(PluginException.class, () -> host.telemetry("cdra", "nope")).getMessage()
                        .contains("no telemetry item 'nope'"));
                assertTrue(assertThrows(PluginException.class, () -> host.execute(CommandKey.parse("run/1.3/1"),
                        "ghost", "x", Map.of()))
                        .getMessage().contains("not bound"));
                assertTrue(host.telemetry("cdra", "filter_locked").stale());
            }
        }
    }

    @Test
    void aCancelStopsTheCommandInFlightAndItsResultSaysHalted() throws Exception {
        try (TestServer server = new TestServer()) {
            BlockingQueue<JsonObject> executes = new LinkedBlockingQueue<>();
            BlockingQueue<JsonObject> halts = new LinkedBlockingQueue<>();
            LedgerResponder habitat = new LedgerResponder(call -> {
                if (!call.has("service")) {
                    return List.of(); // subscriptions of the telemetry plugins
                }
                if (call.get("service").getAsString().endsWith("/halt")) {
                    halts.add(call);
                    return List.of(serviceReply(call, "{\"success\":true,\"message\":\"halted: arm stopped\"}"));
                }
                return List.of(); // execute_command and unlock_filter: the test answers them below
            });
            server.respond(message -> {
                if ("call_service".equals(message.get("op").getAsString())
                        && CommandLedger.EXECUTE_SERVICE.equals(message.get("service").getAsString())) {
                    executes.add(message);
                }
                return habitat.apply(message);
            });
            try (PaxHost host = PaxHost.open(BINDINGS.resolve("iva.yaml"), server.uri())) {
                CommandKey pull = CommandKey.parse("run/2.7/1");
                CompletableFuture<CommandResult> moving = CompletableFuture.supplyAsync(() -> host.execute(pull,
                        "affordance_templates", "execute_plan", Map.of("affordance_template", "cdra_filter:0",
                                "trajectory", "grasp_and_pull")));
                JsonObject sent = executes.poll(5, TimeUnit.SECONDS);
                assertTrue(sent != null, "execute_plan never reached the ledger");
                CancelResult cancel = host.cancel(pull);
                assertEquals(new CancelResult(true, "halted: arm stopped"), cancel);
                JsonObject halt = halts.poll(5, TimeUnit.SECONDS);
                assertEquals("/affordance_template_server/halt", halt.get("service").getAsString());
                assertFalse(halt.has("type"), "the halt's type comes from the ROS graph");
                assertEquals("halt of run/2.7/1", halt.getAsJsonObject("args").get("reason").getAsString());
                server.send(ledgerAnswer(sent, "FAILED", "{\"success\":false,\"message\":\"halted by the operator\"}"));
                CommandResult halted = moving.get(10, TimeUnit.SECONDS);
                assertEquals(Outcome.HALTED, halted.outcome());
                assertEquals("halted by the operator", halted.message());
                assertFalse(host.cancel(pull).stopped(), "nothing runs under that key any more");

                CommandKey unlock = CommandKey.parse("run/2.4/1");
                CompletableFuture<CommandResult> unlocking = CompletableFuture.supplyAsync(() -> host.execute(unlock,
                        "cdra", "unlock_filter", Map.of()));
                JsonObject unlockSent = executes.poll(5, TimeUnit.SECONDS);
                CancelResult refused = host.cancel(unlock);
                assertFalse(refused.stopped());
                assertTrue(refused.message().contains("cannot be cancelled"), refused.message());
                server.send(ledgerAnswer(unlockSent, "SUCCEEDED", "{\"success\":true,\"message\":\"unlocked\"}"));
                assertEquals(Outcome.SUCCEEDED, unlocking.get(10, TimeUnit.SECONDS).outcome(),
                        "a command that finished before the cancel stays succeeded");
            }
        }
    }

    private static JsonObject serviceReply(JsonObject call, String values) {
        JsonObject reply = new JsonObject();
        reply.addProperty("op", "service_response");
        reply.add("id", call.get("id"));
        reply.add("service", call.get("service"));
        reply.add("values", JsonParser.parseString(values));
        reply.addProperty("result", true);
        return reply;
    }

    private static JsonObject ledgerAnswer(JsonObject execute, String state, String response) {
        JsonObject values = new JsonObject();
        values.addProperty("state", state);
        values.addProperty("epoch", LedgerResponder.EPOCH);
        values.addProperty("response_json", response);
        values.addProperty("message", "");
        return serviceReply(execute, values.toString());
    }
}
