// Drives the project's Java rosbridge client (java/pax-plugins, caretaker.rosbridge.Ros) through the
// `clients` cases of `caretaker interop --serve`.
// Usage (Java 11+ runs the source file directly):
//   java -cp pax-plugins.jar:/usr/share/java/gson.jar JavaDriver.java ws://HOST:PORT
// One Ros per case on the case's path, used as a program would use it, and one more on /report that
// tells the server what the program received. The waits are the driver's patience with the client;
// the server's answers to the reports say when a step has been played.

import caretaker.rosbridge.Message;
import caretaker.rosbridge.Ros;
import caretaker.rosbridge.RosAuth;
import caretaker.rosbridge.RosAuthException;
import caretaker.rosbridge.RosException;
import caretaker.rosbridge.RosOptions;
import caretaker.rosbridge.RosTimeoutException;
import caretaker.rosbridge.Service;
import caretaker.rosbridge.ServiceRequest;
import caretaker.rosbridge.ServiceResponse;
import caretaker.rosbridge.Topic;
import com.google.gson.JsonArray;
import com.google.gson.JsonElement;
import com.google.gson.JsonNull;
import com.google.gson.JsonObject;
import com.google.gson.JsonPrimitive;
import java.net.URI;
import java.time.Duration;
import java.util.List;
import java.util.concurrent.CompletableFuture;
import java.util.concurrent.CopyOnWriteArrayList;
import java.util.concurrent.CountDownLatch;
import java.util.concurrent.TimeUnit;

public final class JavaDriver {
    private static final Duration PATIENCE = Duration.ofSeconds(3);

    private final String base;
    private final Ros reporter;
    private final Service reports;

    private JavaDriver(String url) {
        base = url.replaceAll("/+$", "");
        reporter = new Ros(URI.create(base + "/report"), RosOptions.defaults());
        reporter.connect();
        reports = new Service(reporter, "/interop/report", "interop/Report");
    }

    private JsonObject report(String caseId, JsonObject observed) {
        String text = observed.toString();
        System.out.println(caseId + ": " + text.substring(0, Math.min(200, text.length())));
        JsonObject args = new JsonObject();
        args.addProperty("case", caseId);
        args.addProperty("observed", text);
        return reports.callServiceAndWait(new ServiceRequest(args), Duration.ofSeconds(30)).toJsonObject();
    }

    private Ros open(String caseId) {
        Ros ros = new Ros(URI.create(base + "/" + caseId), RosOptions.defaults());
        ros.connect();
        return ros;
    }

    private static JsonElement data(ServiceResponse response) {
        JsonElement value = response.toJsonObject().get("data");
        return value == null ? JsonNull.INSTANCE : value;
    }

    /** What the program got from a call: the answer's data, or the failure's text. */
    private static JsonElement answered(CompletableFuture<ServiceResponse> call) {
        try {
            return data(call.get(PATIENCE.toMillis() * 2, TimeUnit.MILLISECONDS));
        } catch (Exception e) {
            return new JsonPrimitive("error: " + e);
        }
    }

    private static JsonArray array(List<String> items) {
        JsonArray array = new JsonArray();
        items.forEach(array::add);
        return array;
    }

    private void outOfOrder() throws Exception {
        try (Ros ros = open("clients.1")) {
            Service echo = new Service(ros, "/interop/echo", "interop/Echo");
            JsonObject observed = new JsonObject();
            CompletableFuture<ServiceResponse> first = echo.callAsync(new ServiceRequest("{\"data\":\"first\"}"), PATIENCE.multipliedBy(2));
            CompletableFuture<ServiceResponse> second = echo.callAsync(new ServiceRequest("{\"data\":\"second\"}"), PATIENCE.multipliedBy(2));
            observed.add("first", answered(first));
            observed.add("second", answered(second));
            observed.addProperty("done", true);
            report("clients.1", observed);
        }
    }

    private void messages(String caseId, String topic) throws Exception {
        try (Ros ros = open(caseId)) {
            List<String> received = new CopyOnWriteArrayList<>();
            CountDownLatch after = new CountDownLatch(1);
            new Topic(ros, topic, "std_msgs/msg/String").subscribe((Message message) -> {
                String value = message.toJsonObject().get("data").getAsString();
                received.add(value);
                if (value.equals("after")) {
                    after.countDown();
                }
            });
            after.await(PATIENCE.toMillis(), TimeUnit.MILLISECONDS);
            JsonObject observed = new JsonObject();
            observed.add("received", array(received));
            observed.add("status", JsonNull.INSTANCE); // status messages go to the log only
            observed.addProperty("done", true);
            report(caseId, observed);
        }
    }

    private void dropped() throws Exception {
        try (Ros ros = open("clients.4")) {
            List<String> received = new CopyOnWriteArrayList<>();
            CountDownLatch arrived = new CountDownLatch(1);
            new Topic(ros, "/interop/drop", "std_msgs/msg/String").subscribe((Message message) -> {
                String value = message.toJsonObject().get("data").getAsString();
                received.add(value);
                if (value.equals("after-reconnect")) {
                    arrived.countDown();
                }
            });
            new Topic(ros, "/interop/drop_pub", "std_msgs/msg/String").advertise();
            // this client serves no ROS services (no advertiseService)
            JsonObject registered = new JsonObject();
            registered.add("registered", array(List.of("subscribe /interop/drop", "advertise /interop/drop_pub")));
            JsonObject answer = report("clients.4", registered);
            if (answer.has("reconnected") && answer.get("reconnected").getAsBoolean()) {
                arrived.await(PATIENCE.toMillis(), TimeUnit.MILLISECONDS);
            }
            JsonObject observed = new JsonObject();
            observed.add("received", array(received));
            observed.addProperty("done", true);
            report("clients.4", observed);
        }
    }

    private void slow() throws Exception {
        try (Ros ros = open("clients.5")) {
            String outcome;
            try {
                new Service(ros, "/interop/slow", "interop/Echo").callServiceAndWait(new ServiceRequest(), Duration.ofMillis(500));
                outcome = "answered";
            } catch (RosTimeoutException e) {
                outcome = "timed out";
            } catch (RosException e) {
                outcome = "error: " + e.getMessage();
            }
            JsonObject slow = new JsonObject();
            slow.addProperty("timeout_offered", true);
            slow.addProperty("slow_call", outcome);
            report("clients.5", slow);
            JsonObject observed = new JsonObject();
            try {
                observed.add("after_late", data(new Service(ros, "/interop/echo", "interop/Echo")
                        .callServiceAndWait(new ServiceRequest("{\"data\":\"after-late\"}"), PATIENCE)));
            } catch (RosException e) {
                observed.addProperty("after_late", "error: " + e.getMessage());
            }
            observed.addProperty("done", true);
            report("clients.5", observed);
        }
    }

    private void refusedAuth() {
        Ros ros = new Ros(URI.create(base + "/clients.6"),
                RosOptions.defaults().withAuth(RosAuth.hmac("not the server's secret")));
        JsonObject observed = new JsonObject();
        observed.addProperty("auth_offered", true);
        try {
            ros.connect();
            observed.add("refusal", JsonNull.INSTANCE);
            observed.addProperty("closed", false);
        } catch (RosAuthException e) {
            observed.addProperty("refusal", e.getMessage());
            observed.addProperty("closed", true);
        } catch (RosException e) {
            observed.add("refusal", JsonNull.INSTANCE);
            observed.addProperty("closed", true);
            observed.addProperty("error", e.getMessage());
        }
        observed.addProperty("connected", ros.isConnected());
        observed.addProperty("done", true);
        report("clients.6", observed);
        ros.close();
    }

    public static void main(String[] args) throws Exception {
        if (args.length != 1 || !args[0].matches("wss?://.*")) {
            System.err.println("usage: java -cp pax-plugins.jar:gson.jar JavaDriver.java ws://HOST:PORT");
            System.exit(2);
        }
        JavaDriver driver = new JavaDriver(args[0]);
        JsonObject hello = new JsonObject();
        hello.addProperty("client", "caretaker.rosbridge (java/pax-plugins)");
        driver.report("hello", hello);
        driver.outOfOrder();
        driver.messages("clients.2", "/interop/fragmented");
        driver.messages("clients.3", "/interop/status_after");
        driver.dropped();
        driver.slow();
        driver.refusedAuth();
        driver.report("bye", new JsonObject());
        driver.reporter.close();
        System.exit(0);
    }
}
