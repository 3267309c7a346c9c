package caretaker.rosbridge;

import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.time.Duration;
import java.time.Instant;
import java.util.List;
import java.util.concurrent.CopyOnWriteArrayList;
import java.util.concurrent.atomic.AtomicInteger;

/**
 * State-changing commands through the habitat's command ledger ({@code caretaker ledger}): each
 * command key executes at most once, and its real outcome is learnt across link outages.
 *
 * <p>{@link #execute} sends the call through {@code /command_ledger/execute} with the key. When
 * the connection drops or the reply does not come, it waits for the connection to come back (at
 * most the link's outage budget, counted from when the link was lost) and sends the same key
 * again, with the ledger epoch it knew before the first send: the ledger answers the recorded
 * outcome or joins the call still running, and answers UNKNOWN if its memory was lost meanwhile.
 * Past the budget the answer is {@link LedgerState#UNKNOWN} if the command may have left, and
 * {@link LedgerState#REFUSED} if it certainly never did. An answer of the system is never
 * changed: FAILED stays FAILED, UNKNOWN stays UNKNOWN.
 *
 * <p>A ledger may be <em>required</em> (a binding that states a link requires one): then a
 * habitat without one gets nothing — {@link #probe} throws {@link LedgerMissingException}, and a
 * command waits for a ledger within the outage budget (one may be restarting) and is then refused
 * as never sent. When it is not required (a loopback binding), a habitat without a ledger (none
 * ever answered on this connection) gets the call directly, logged as a warning: at most once
 * still holds (nothing is re-sent), but a lost reply makes the outcome UNKNOWN instead of being
 * learnt.
 *
 * <p>Listeners hear the link's state: connected, or lost since T with N commands in flight.
 * Thread-safe; one per {@link Ros}.
 */
public final class CommandLedger implements AutoCloseable {
    private static final System.Logger LOG = System.getLogger(CommandLedger.class.getName());
    /** The ledger's execute service (in the ledger's namespace, if it has one). */
    public static final String EXECUTE_SERVICE = "/command_ledger/execute";
    /** The ledger's outcome query service (in the ledger's namespace, if it has one). */
    public static final String OUTCOME_SERVICE = "/command_ledger/outcome";
    private static final String EXECUTE_TYPE = "caretaker_ledger_msgs/srv/ExecuteOnce";
    private static final String OUTCOME_TYPE = "caretaker_ledger_msgs/srv/CommandOutcome";
    /** Time the ledger may need beyond a command's own timeout: discovery, server match, disk. */
    private static final Duration LEDGER_MARGIN = Duration.ofSeconds(10);
    /** Time for the answer to travel beyond the round trip (processing on both ends). */
    private static final Duration REPLY_MARGIN = Duration.ofSeconds(2);
    /** Texts of rosbridge failures that mean the called service was never reached. */
    private static final List<String> NOT_REACHED = List.of("does not exist", "has no server", "is not allowed");
    /** Texts of rosbridge failures that pass: the service is not discovered yet, restarting, or slow. */
    private static final List<String> PASSING = List.of("does not exist", "has no server", "Timeout exceeded",
            "lost its server");
    /** How long "no ledger on this habitat" is believed before asking again. */
    private static final Duration ABSENCE_RECHECK = Duration.ofSeconds(30);
    /** Pause before asking again when the habitat answered but not yet usefully (a restarting ledger). */
    private static final Duration RETRY_PAUSE = Duration.ofMillis(500);

    private final Ros ros;
    private final LinkOptions link;
    private final boolean required;
    private final Service executeService;
    private final Service outcomeService;
    private final List<LinkListener> listeners = new CopyOnWriteArrayList<>();
    private final AtomicInteger inFlight = new AtomicInteger();
    private final RosHandler linkWatcher;
    /** The ledger's epoch as last heard; null until heard. */
    private volatile String epoch;
    /** Whether a ledger answered on this connection: null not asked yet, FALSE none found yet. */
    private volatile Boolean present;
    /** When FALSE {@link #present} is to be asked again (System.nanoTime). */
    private volatile long recheckNanos;

    /**
     * A ledger client that falls back to direct calls on a habitat without a ledger.
     *
     * @param ros the connection to the habitat's rosbridge
     * @param link the link's delay and outage budget
     */
    public CommandLedger(Ros ros, LinkOptions link) {
        this(ros, link, false, "");
    }

    /**
     * @param ros the connection to the habitat's rosbridge
     * @param link the link's delay and outage budget
     * @param required no direct calls: a habitat without a ledger gets no command
     * @param namespace the ROS namespace of the habitat's ledger ("" = root; a robot that shares
     *     its ROS graph with others has its ledger in its own namespace, e.g. {@code /bench})
     */
    public CommandLedger(Ros ros, LinkOptions link, boolean required, String namespace) {
        this.ros = ros;
        this.link = link;
        this.required = required;
        this.executeService = new Service(ros, namespace + EXECUTE_SERVICE, EXECUTE_TYPE);
        this.outcomeService = new Service(ros, namespace + OUTCOME_SERVICE, OUTCOME_TYPE);
        this.linkWatcher = new RosHandler() {
            @Override
            public void handleConnection() {
                if (Boolean.FALSE.equals(present)) {
                    present = null; // the habitat may have gained a ledger: ask again
                }
                tellListeners();
            }

            @Override
            public void handleDisconnection() {
                tellListeners();
            }

            @Override
            public void handleQuiet(Instant since) {
                tellListeners();
            }
        };
        ros.addRosHandler(linkWatcher);
    }

    /** @return the link's delay and outage budget */
    public LinkOptions link() {
        return link;
    }

    /**
     * Executes a state-changing ROS service call at most once and learns its outcome.
     *
     * @param commandKey {@code run/instruction/attempt}; the same key always means this call
     * @param service the ROS service, e.g. {@code /cdra/unlock_filter}
     * @param type its type, or null to let the habitat take it from the ROS graph
     * @param request the request
     * @param timeout how long the service may take to answer (on the habitat)
     * @return the outcome; never an exception for link trouble
     */
    public LedgerAnswer execute(String commandKey, String service, String type, JsonObject request,
            Duration timeout) {
        changeInFlight(1);
        try {
            return new Attempt(commandKey, service, type, request, timeout).run();
        } finally {
            changeInFlight(-1);
        }
    }

    /**
     * A read-only call (it may run twice): waits for the link within the outage budget, and
     * calls again after a drop.
     *
     * @param service a service that changes nothing
     * @param request the request
     * @param timeout how long it may take to answer
     * @return the reply
     * @throws ServiceFailedException rosbridge answered with a failure
     * @throws RosException no answer within the outage budget
     */
    public ServiceResponse query(Service service, JsonObject request, Duration timeout) {
        Outage outage = new Outage();
        while (true) {
            try {
                outage.awaitLink();
                return service.callServiceAndWait(new ServiceRequest(request), timeout.plus(link.roundTrip()),
                        timeout);
            } catch (ServiceFailedException | RosAuthException e) {
                throw e;
            } catch (RosException e) {
                outage.began(e);
                if (outage.over()) {
                    throw new RosException(outage.describe() + ", " + service.getName() + " not answered", e);
                }
            }
        }
    }

    /**
     * Asks the ledger what became of a key, executing nothing.
     *
     * @param commandKey the key
     * @param timeout how long to wait for the answer
     * @return the ledger's record (state IN_PROGRESS or NOT_FOUND included)
     * @throws RosException no answer (no ledger, no link)
     */
    public LedgerAnswer outcome(String commandKey, Duration timeout) {
        JsonObject request = new JsonObject();
        request.addProperty("command_key", commandKey);
        JsonObject reply = outcomeService.callServiceAndWait(new ServiceRequest(request),
                timeout.plus(link.roundTrip()), timeout).toJsonObject();
        present = Boolean.TRUE;
        return answer(reply);
    }

    /**
     * Learns whether the habitat has a command ledger, and its epoch.
     *
     * @param timeout how long to wait for the answer
     * @return true if a ledger answered; false if the habitat has none (commands then go directly)
     * @throws LedgerMissingException the habitat has none, and one is required
     * @throws RosAuthException the bridge refused this client's authentication
     * @throws RosException no answer
     */
    public boolean probe(Duration timeout) {
        try {
            outcome("", timeout);
            return true;
        } catch (ServiceFailedException e) {
            if (!notReached(e)) {
                throw e;
            }
            if (required) {
                throw new LedgerMissingException("no command ledger at " + ros.getUri() + " (" + e.getReason()
                        + "); commands over a stated link go only through it, to be executed at most once: start"
                        + " it on the habitat (`caretaker up` does, or `caretaker ledger --state-dir DIR`)");
            }
            LOG.log(System.Logger.Level.WARNING, "no command ledger at " + ros.getUri() + " (" + e.getReason()
                    + "): commands go directly; a lost reply leaves the outcome UNKNOWN (start `caretaker"
                    + " ledger` on the habitat)");
            present = Boolean.FALSE;
            recheckNanos = System.nanoTime() + ABSENCE_RECHECK.toNanos();
            return false;
        }
    }

    /** @return the link's state now */
    public LinkState linkState() {
        boolean connected = ros.isConnected();
        return new LinkState(ros.getUri(), connected, connected ? null : ros.lostSince(), inFlight.get(),
                connected ? ros.quietSince() : null);
    }

    /** @param listener told about link state changes */
    public void addLinkListener(LinkListener listener) {
        listeners.add(listener);
    }

    /** @param listener a listener added before */
    public void removeLinkListener(LinkListener listener) {
        listeners.remove(listener);
    }

    /** Stops listening to the connection (which belongs to the caller). */
    @Override
    public void close() {
        ros.removeRosHandler(linkWatcher);
    }

    private void changeInFlight(int delta) {
        inFlight.addAndGet(delta);
        if (!ros.isConnected() || ros.quietSince() != null) {
            tellListeners();
        }
    }

    private void tellListeners() {
        // read when it runs on the one callback thread, so the last state told is the state now
        ros.dispatch(() -> {
            LinkState state = linkState();
            for (LinkListener listener : listeners) {
                listener.linkChanged(state);
            }
        });
    }

    /** Parses a ledger reply {state, epoch, response_json, message}; unreadable parts make it UNKNOWN. */
    private LedgerAnswer answer(JsonObject reply) {
        String heard = text(reply, "epoch");
        if (!heard.isEmpty()) {
            epoch = heard;
        }
        String message = text(reply, "message");
        LedgerState state;
        try {
            state = LedgerState.valueOf(text(reply, "state"));
        } catch (IllegalArgumentException e) {
            return new LedgerAnswer(LedgerState.UNKNOWN, null, "the ledger answered an unknown state '"
                    + text(reply, "state") + "': " + message);
        }
        String responseJson = text(reply, "response_json");
        if (responseJson.isEmpty()) {
            return new LedgerAnswer(state, null, message);
        }
        try {
            return new LedgerAnswer(state, JsonParser.parseString(responseJson).getAsJsonObject(), message);
        } catch (RuntimeException e) {
            return new LedgerAnswer(LedgerState.UNKNOWN, null, "the ledger's response_json is not a JSON object: "
                    + message);
        }
    }

    private static String text(JsonObject reply, String field) {
        JsonElement value = reply.get(field);
        return value != null && value.isJsonPrimitive() ? value.getAsString() : "";
    }

    private static boolean notReached(ServiceFailedException e) {
        return NOT_REACHED.stream().anyMatch(e.getReason()::contains);
    }

    private static boolean passing(ServiceFailedException e) {
        return PASSING.stream().anyMatch(e.getReason()::contains);
    }

    /** Whether to ask (again) whether the habitat has a ledger and what its epoch is. */
    private boolean mustProbe() {
        Boolean known = present;
        return known == null || (known && epoch == null) || (!known && System.nanoTime() - recheckNanos > 0);
    }

    /** How long one command has been cut off from the habitat, against the outage budget. */
    private final class Outage {
        /** When the trouble began (when the link was last heard, if it knows); null: no trouble. */
        private Instant since;
        /** The latest failure, for the message. */
        private String latest = "";

        /**
         * The link failed now (or earlier, if the connection knows when it was lost).
         *
         * @param failure what failed
         */
        void began(RosException failure) {
            latest = failure.getMessage();
            if (since == null) { // a quiet link: from when the habitat was last heard, as a lost one
                Instant lost = ros.isConnected() ? ros.quietSince() : ros.lostSince();
                since = lost != null ? lost : Instant.now();
            }
        }

        /** The habitat answered: trouble, if any, is over. */
        void ended() {
            since = null;
        }

        boolean over() {
            return since != null && Duration.between(since, Instant.now()).compareTo(link.outageBudget()) >= 0;
        }

        /** Waits for the connection within what is left of the budget. */
        void awaitLink() {
            if (ros.isConnected()) {
                return;
            }
            NotConnectedException down = new NotConnectedException("not connected to rosbridge at " + ros.getUri());
            began(down);
            Duration left = link.outageBudget().minus(Duration.between(since, Instant.now()));
            try {
                ros.awaitConnected(left.isNegative() || left.isZero() ? Duration.ofMillis(1) : left);
            } catch (RosTimeoutException e) {
                throw down;
            }
        }

        /** @return "link lost since T (what failed last)" */
        String describe() {
            return "link lost since " + since + " (" + latest + ")";
        }
    }

    /** One command's sends, until its outcome is learnt or the budget is spent. */
    private final class Attempt {
        private final String key;
        private final String service;
        private final String type;
        private final JsonObject request;
        private final Duration timeout;
        private final Outage outage = new Outage();
        /** Whether a send may have reached the habitat. */
        private boolean maybeSent;
        /** The epoch known before the first send that may have left: re-sends carry it. */
        private String firstEpoch = "";

        Attempt(String key, String service, String type, JsonObject request, Duration timeout) {
            this.key = key;
            this.service = service;
            this.type = type;
            this.request = request;
            this.timeout = timeout;
        }

        LedgerAnswer run() {
            while (true) {
                try {
                    outage.awaitLink();
                    if (mustProbe()) {
                        probe();
                    }
                    LedgerAnswer answer = Boolean.TRUE.equals(present) ? send() : direct();
                    if (answer != null) {
                        return answer;
                    }
                } catch (RosAuthException e) {
                    return givenUp(e.getMessage());
                } catch (RosException e) {
                    outage.began(e);
                }
                if (outage.over()) {
                    return givenUp(outage.describe() + ", outage budget of "
                            + Durations.seconds(link.outageBudget()) + " s spent");
                }
                if (ros.isConnected() && !pause()) { // the habitat answered, not yet usefully: no busy loop
                    return givenUp("interrupted while waiting to send again");
                }
            }
        }

        /** @return false if interrupted (the flag is set again) */
        private boolean pause() {
            try {
                Thread.sleep(RETRY_PAUSE.toMillis());
                return true;
            } catch (InterruptedException e) {
                Thread.currentThread().interrupt();
                return false;
            }
        }

        private void probe() {
            CommandLedger.this.probe(ros.getOptions().timeout());
            outage.ended();
        }

        /** One send through the ledger; null when it must be sent again. */
        private LedgerAnswer send() {
            if (!maybeSent) {
                firstEpoch = epoch == null ? "" : epoch;
            }
            JsonObject args = new JsonObject();
            args.addProperty("command_key", key);
            args.addProperty("epoch", maybeSent ? firstEpoch : "");
            args.addProperty("service", service);
            args.addProperty("type", type == null ? "" : type);
            args.addProperty("request_json", request.toString());
            args.addProperty("timeout", timeout.toNanos() / 1e9);
            Duration serverTimeout = timeout.plus(LEDGER_MARGIN);
            Duration wait = serverTimeout.plus(link.roundTrip()).plus(REPLY_MARGIN);
            try {
                JsonObject reply = executeService.callServiceAndWait(new ServiceRequest(args), wait, serverTimeout)
                        .toJsonObject();
                return answer(reply);
            } catch (NotConnectedException e) {
                throw e; // nothing left: a first send stays a first send
            } catch (ServiceFailedException e) {
                if (!passing(e)) { // refused by the bridge for good: sending again cannot help
                    return maybeSent || !notReached(e) ? new LedgerAnswer(LedgerState.UNKNOWN, null, e.getMessage())
                            : new LedgerAnswer(LedgerState.REFUSED, null, e.getMessage());
                }
                // The ledger is not discovered yet, restarting, or too slow: the same key goes again.
                maybeSent |= !notReached(e);
                outage.began(e);
                return null;
            } catch (RosException e) {
                maybeSent = true;
                throw e;
            }
        }

        /** The call without a ledger: sent once, never again. */
        private LedgerAnswer direct() {
            Service target = new Service(ros, service, type);
            try {
                JsonObject reply = target.callServiceAndWait(new ServiceRequest(request),
                        timeout.plus(link.roundTrip()).plus(REPLY_MARGIN), timeout).toJsonObject();
                JsonElement success = reply.get("success");
                boolean failed = success != null && success.isJsonPrimitive() && !success.getAsBoolean();
                return new LedgerAnswer(failed ? LedgerState.FAILED : LedgerState.SUCCEEDED, reply, text(reply,
                        "message"));
            } catch (NotConnectedException e) {
                throw e;
            } catch (ServiceFailedException e) {
                return notReached(e) ? new LedgerAnswer(LedgerState.REFUSED, null, e.getMessage())
                        : new LedgerAnswer(LedgerState.UNKNOWN, null, e.getMessage() + "; it may have executed");
            } catch (RosException e) {
                return new LedgerAnswer(LedgerState.UNKNOWN, null, e.getMessage() + "; with no command ledger on"
                        + " the habitat the outcome cannot be learnt");
            }
        }

        private LedgerAnswer givenUp(String why) {
            if (maybeSent) {
                return new LedgerAnswer(LedgerState.UNKNOWN, null, why + ": outcome of " + key + " not learnt");
            }
            return new LedgerAnswer(LedgerState.REFUSED, null, why + ": " + key + " was never sent");
        }
    }
}
