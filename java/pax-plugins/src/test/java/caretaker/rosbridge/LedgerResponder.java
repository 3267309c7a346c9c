package caretaker.rosbridge;

import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.util.List;
import java.util.Map;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.ConcurrentHashMap;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import java.util.function.Function;

/**
 * A {@link TestServer} responder that plays the habitat's command ledger in front of another
 * responder (the system): an execute request becomes one {@code call_service} to the system per
 * key (queued for {@link #next()}), and its reply is recorded and wrapped as the ledger answers.
 * Other messages go to the system as they are. The real ledger is tested in tests/ledger.
 */
public final class LedgerResponder implements Function<JsonObject, List<JsonObject>> {
    /** The epoch this ledger answers with. */
    public static final String EPOCH = "test-epoch";

    private final Function<JsonObject, List<JsonObject>> system;
    private final Map<String, JsonObject> recorded = new ConcurrentHashMap<>();
    private final BlockingQueue<JsonObject> calls = new LinkedBlockingQueue<>();

    /** @param system answers the calls the ledger makes, as a rosbridge server would */
    public LedgerResponder(Function<JsonObject, List<JsonObject>> system) {
        this.system = system;
    }

    /** @return the next call the ledger made to the system, waiting up to 5 s */
    public JsonObject next() throws InterruptedException {
        JsonObject call = calls.poll(5, TimeUnit.SECONDS);
        if (call == null) {
            throw new AssertionError("the ledger made no call within 5 s");
        }
        return call;
    }

    @Override
    public List<JsonObject> apply(JsonObject message) {
        if (!"call_service".equals(message.get("op").getAsString())) {
            return system.apply(message);
        }
        String service = message.get("service").getAsString();
        if (service.equals(CommandLedger.OUTCOME_SERVICE)) {
            JsonObject values = new JsonObject();
            values.addProperty("state", "NOT_FOUND");
            values.addProperty("epoch", EPOCH);
            return List.of(reply(message, values));
        }
        if (!service.equals(CommandLedger.EXECUTE_SERVICE)) {
            return system.apply(message);
        }
        JsonObject args = message.getAsJsonObject("args");
        String key = args.get("command_key").getAsString();
        JsonObject values = recorded.get(key);
        if (values == null) {
            JsonObject call = new JsonObject();
            call.addProperty("op", "call_service");
            call.addProperty("id", "ledger:" + key);
            call.add("service", args.get("service"));
            if (!args.get("type").getAsString().isEmpty()) {
                call.add("type", args.get("type"));
            }
            call.add("args", JsonParser.parseString(args.get("request_json").getAsString()));
            calls.add(call);
            List<JsonObject> answers = system.apply(call);
            if (answers.isEmpty()) {
                return List.of();
            }
            JsonObject answer = answers.get(0);
            values = new JsonObject();
            values.addProperty("epoch", EPOCH);
            if (answer.get("result").getAsBoolean()) {
                JsonObject response = answer.getAsJsonObject("values");
                boolean failed = response.has("success") && !response.get("success").getAsBoolean();
                values.addProperty("state", failed ? "FAILED" : "SUCCEEDED");
                values.addProperty("response_json", response.toString());
                values.addProperty("message", response.has("message") ? response.get("message").getAsString() : "");
            } else {
                values.addProperty("state", "REFUSED");
                values.addProperty("message", answer.get("values").getAsString());
            }
            recorded.put(key, values);
        }
        return List.of(reply(message, values));
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
}
