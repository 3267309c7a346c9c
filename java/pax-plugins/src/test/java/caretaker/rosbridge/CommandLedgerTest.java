package caretaker.rosbridge;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertNull;
import static org.junit.jupiter.api.Assertions.assertTrue;

import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.io.IOException;
import java.io.UncheckedIOException;
import java.time.Duration;
import java.util.List;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.CompletableFuture;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import java.util.function.Function;
import org.junit.jupiter.api.AfterEach;
import org.junit.jupiter.api.BeforeEach;
import org.junit.jupiter.api.Test;

/**
 * The ledger client against a {@link TestServer} playing rosbridge and the ledger: the same key and
 * epoch re-sent after a dropped connection, UNKNOWN past the outage budget, never-sent commands,
 * a habitat without a ledger, link states. The real ledger is tested in tests/ledger.
 */
class CommandLedgerTest {
    private static final RosOptions FAST = new RosOptions(Duration.ofSeconds(5), Duration.ofMillis(50),
            Duration.ofMillis(200));
    private static final JsonObject REQUEST = JsonParser.parseString("{\"data\":true}").getAsJsonObject();

    private TestServer server;
    private Ros ros;
    private final BlockingQueue<JsonObject> executes = new LinkedBlockingQueue<>();
    private final BlockingQueue<LinkState> states = new LinkedBlockingQueue<>();

    @BeforeEach
    void start() throws Exception {
        server = new TestServer();
        ros = new Ros(server.uri(), FAST);
        ros.connect();
    }

    @AfterEach
    void stop() throws IOException {
        ros.close();
        server.close();
    }

    private CommandLedger ledger(Duration budget) {
        CommandLedger ledger = new CommandLedger(ros, new LinkOptions(Duration.ZERO, budget));
        ledger.addLinkListener(states::add);
        return ledger;
    }

    private static JsonObject reply(JsonObject call, JsonObject values) {
        JsonObject reply = new JsonObject();
        reply.addProperty("op", "service_response");
        reply.add("id", call.get("id"));
        reply.add("service", call.get("service"));
        reply.add("values", values);
        reply.addProperty("result", true);
        return reply;
    }

    private static JsonObject values(String state, String responseJson) {
        JsonObject values = new JsonObject();
        values.addProperty("state", state);
        values.addProperty("epoch", "E1");
        values.addProperty("response_json", responseJson);
        values.addProperty("message", state.toLowerCase());
        return values;
    }

    /** A ledger that knows epoch E1; execute requests are queued and answered by {@code answer} (none: no reply). */
    private Function<JsonObject, List<JsonObject>> ledgerServer(Function<JsonObject, JsonObject> answer) {
        return call -> {
            if (!"call_service".equals(call.get("op").getAsString())) {
                return List.of();
            }
            if (call.get("service").getAsString().equals(CommandLedger.OUTCOME_SERVICE)) {
                return List.of(reply(call, values("NOT_FOUND", "")));
            }
            executes.add(call.getAsJsonObject("args"));
            JsonObject values = answer.apply(call);
            return values == null ? List.of() : List.of(reply(call, values));
        };
    }

    private CompletableFuture<LedgerAnswer> execute(CommandLedger ledger, String key) {
        return CompletableFuture.supplyAsync(() -> ledger.execute(key, "/peer/set", "std_srvs/srv/SetBool", REQUEST,
                Duration.ofSeconds(5)));
    }

    @Test
    void aDroppedConnectionIsRidOutByResendingTheSameKeyAndEpoch() throws Exception {
        server.respond(ledgerServer(call -> executes.size() == 1 ? null
                : values("SUCCEEDED", "{\"success\":true,\"message\":\"set true\"}")));
        try (CommandLedger ledger = ledger(Duration.ofSeconds(20))) {
            CompletableFuture<LedgerAnswer> answer = execute(ledger, "run-1/2.1/1");
            JsonObject first = executes.poll(5, TimeUnit.SECONDS);
            server.dropClient();
            LedgerAnswer outcome = answer.get(20, TimeUnit.SECONDS);
            assertEquals(LedgerState.SUCCEEDED, outcome.state());
            assertEquals("set true", outcome.response().get("message").getAsString());
            JsonObject second = executes.poll(5, TimeUnit.SECONDS);
            assertEquals("run-1/2.1/1", first.get("command_key").getAsString());
            assertEquals(first.get("command_key"), second.get("command_key"));
            assertEquals("", first.get("epoch").getAsString(), "a first send claims no history");
            assertEquals("E1", second.get("epoch").getAsString(), "a re-send carries the epoch known before");
            assertEquals(first.get("request_json"), second.get("request_json"));
            assertEquals("std_srvs/srv/SetBool", first.get("type").getAsString());
            LinkState lost = states.poll(5, TimeUnit.SECONDS);
            assertFalse(lost.connected());
            assertEquals(1, lost.commandsInFlight());
            assertTrue(lost.toString().contains("lost since") && lost.toString().contains("1 command in flight"),
                    lost.toString());
            LinkState back = states.poll(5, TimeUnit.SECONDS);
            assertTrue(back.connected(), back.toString());
        }
    }

    @Test
    void pastTheOutageBudgetAnOutcomeNotLearntIsUnknown() throws Exception {
        server.respond(ledgerServer(call -> null));
        try (CommandLedger ledger = ledger(Duration.ofMillis(800))) {
            CompletableFuture<LedgerAnswer> answer = execute(ledger, "run-1/3.1/1");
            executes.poll(5, TimeUnit.SECONDS);
            server.close(); // the habitat is gone for good
            LedgerAnswer outcome = answer.get(20, TimeUnit.SECONDS);
            assertEquals(LedgerState.UNKNOWN, outcome.state());
            assertNull(outcome.response());
            assertTrue(outcome.message().startsWith("link lost since"), outcome.message());
            assertTrue(outcome.message().contains("outcome of run-1/3.1/1 not learnt"), outcome.message());
        }
    }

    @Test
    void aCommandThatNeverLeftIsRefusedNotUnknown() throws Exception {
        try (CommandLedger ledger = ledger(Duration.ofMillis(500))) {
            server.close();
            while (ros.isConnected()) {
                states.poll(5, TimeUnit.SECONDS);
            }
            LedgerAnswer outcome = ledger.execute("run-1/4.1/1", "/peer/set", null, REQUEST, Duration.ofSeconds(5));
            assertEquals(LedgerState.REFUSED, outcome.state());
            assertTrue(outcome.message().contains("not connected") && outcome.message().contains("never sent"),
                    outcome.message());
        }
    }

    @Test
    void theSystemsAnswerIsKeptAsItIs() throws Exception {
        server.respond(ledgerServer(call -> values("FAILED", "{\"success\":false,\"message\":\"jammed\"}")));
        try (CommandLedger ledger = ledger(Duration.ofSeconds(5))) {
            LedgerAnswer failed = ledger.execute("run-1/5.1/1", "/peer/set", null, REQUEST, Duration.ofSeconds(5));
            assertEquals(LedgerState.FAILED, failed.state());
            assertEquals("jammed", failed.response().get("message").getAsString());
        }
        server.respond(ledgerServer(call -> values("UNKNOWN", "")));
        try (CommandLedger ledger = ledger(Duration.ofSeconds(5))) {
            assertEquals(LedgerState.UNKNOWN, ledger.execute("run-1/5.2/1", "/peer/set", null, REQUEST,
                    Duration.ofSeconds(5)).state());
        }
    }

    @Test
    void aBridgeThatRefusesTheLedgerCallForGoodIsNotAskedAgain() throws Exception {
        server.respond(call -> {
            if (!"call_service".equals(call.get("op").getAsString())) {
                return List.of();
            }
            JsonObject reply = new JsonObject();
            reply.addProperty("op", "service_response");
            reply.add("id", call.get("id"));
            reply.add("service", call.get("service"));
            if (call.get("service").getAsString().equals(CommandLedger.OUTCOME_SERVICE)) {
                reply.add("values", values("NOT_FOUND", ""));
                reply.addProperty("result", true);
            } else {
                executes.add(call);
                reply.addProperty("values", "service /command_ledger/execute is not allowed by this bridge");
                reply.addProperty("result", false);
            }
            return List.of(reply);
        });
        try (CommandLedger ledger = ledger(Duration.ofSeconds(20))) {
            LedgerAnswer refused = ledger.execute("run-1/7.1/1", "/peer/set", null, REQUEST, Duration.ofSeconds(5));
            assertEquals(LedgerState.REFUSED, refused.state());
            assertTrue(refused.message().contains("is not allowed"), refused.message());
            assertEquals(1, executes.size());
        }
    }

    @Test
    void withoutALedgerTheCallIsDirectAndALostReplyIsUnknown() throws Exception {
        List<JsonObject> direct = new java.util.concurrent.CopyOnWriteArrayList<>();
        server.respond(call -> {
            if (!"call_service".equals(call.get("op").getAsString())) {
                return List.of();
            }
            String service = call.get("service").getAsString();
            JsonObject reply = new JsonObject();
            reply.addProperty("op", "service_response");
            reply.add("id", call.get("id"));
            reply.add("service", call.get("service"));
            if (service.startsWith("/command_ledger/")) {
                reply.addProperty("values", "Service " + service + " does not exist");
                reply.addProperty("result", false);
                return List.of(reply);
            }
            direct.add(call);
            if (direct.size() > 1) {
                try {
                    server.dropClient();
                } catch (IOException e) {
                    throw new UncheckedIOException(e);
                }
                return List.of();
            }
            reply.add("values", JsonParser.parseString("{\"success\":true,\"message\":\"ok\"}"));
            reply.addProperty("result", true);
            return List.of(reply);
        });
        try (CommandLedger ledger = ledger(Duration.ofSeconds(5))) {
            LedgerAnswer done = ledger.execute("run-1/6.1/1", "/peer/set", null, REQUEST, Duration.ofSeconds(5));
            assertEquals(LedgerState.SUCCEEDED, done.state());
            assertEquals(REQUEST, direct.get(0).get("args"));
            LedgerAnswer lost = ledger.execute("run-1/6.2/1", "/peer/set", null, REQUEST, Duration.ofSeconds(5));
            assertEquals(LedgerState.UNKNOWN, lost.state());
            assertTrue(lost.message().contains("no command ledger"), lost.message());
            assertEquals(2, direct.size(), "each sent once, never re-sent");
        }
    }

    @Test
    void aRequiredLedgerIsNeverBypassed() throws Exception {
        List<JsonObject> direct = new java.util.concurrent.CopyOnWriteArrayList<>();
        server.respond(call -> {
            if (!"call_service".equals(call.get("op").getAsString())) {
                return List.of();
            }
            String service = call.get("service").getAsString();
            if (!service.startsWith("/bench/command_ledger/")) {
                direct.add(call);
            }
            JsonObject reply = new JsonObject();
            reply.addProperty("op", "service_response");
            reply.add("id", call.get("id"));
            reply.add("service", call.get("service"));
            reply.addProperty("values", "Service " + service + " does not exist");
            reply.addProperty("result", false);
            return List.of(reply);
        });
        try (CommandLedger ledger = new CommandLedger(ros, new LinkOptions(Duration.ZERO, Duration.ofSeconds(2)),
                true, "/bench")) {
            LedgerMissingException missing = org.junit.jupiter.api.Assertions.assertThrows(
                    LedgerMissingException.class, () -> ledger.probe(Duration.ofSeconds(5)));
            assertTrue(missing.getMessage().contains("no command ledger at " + server.uri())
                    && missing.getMessage().contains("/bench/command_ledger/outcome does not exist")
                    && missing.getMessage().contains("caretaker up"), missing.getMessage());
            LedgerAnswer refused = ledger.execute("run-1/7.1/1", "/peer/set", null, REQUEST, Duration.ofSeconds(5));
            assertEquals(LedgerState.REFUSED, refused.state());
            assertTrue(refused.message().contains("was never sent") && refused.message().contains("no command ledger"),
                    refused.message());
            assertTrue(direct.isEmpty(), "no direct call where a ledger is required: " + direct);
        }
    }

    @Test
    void aReadOnlyQueryIsAskedAgainAfterADrop() throws Exception {
        BlockingQueue<JsonObject> asked = new LinkedBlockingQueue<>();
        server.respond(call -> {
            if (!"call_service".equals(call.get("op").getAsString())) {
                return List.of();
            }
            asked.add(call);
            if (asked.size() == 1) {
                return List.of();
            }
            return List.of(reply(call, JsonParser.parseString("{\"templates\":[\"a:0\"]}").getAsJsonObject()));
        });
        try (CommandLedger ledger = ledger(Duration.ofSeconds(20))) {
            CompletableFuture<ServiceResponse> reply = CompletableFuture.supplyAsync(() -> ledger.query(
                    new Service(ros, "/at/get_running", null), new JsonObject(), Duration.ofSeconds(5)));
            asked.poll(5, TimeUnit.SECONDS);
            server.dropClient();
            assertEquals("a:0", reply.get(20, TimeUnit.SECONDS).toJsonObject().getAsJsonArray("templates").get(0)
                    .getAsString());
        }
    }
}
