package caretaker.rosbridge;

import com.google.gson.JsonObject;
import java.time.Duration;
import java.util.concurrent.CompletableFuture;
import java.util.concurrent.ExecutionException;
import java.util.concurrent.TimeUnit;
import java.util.concurrent.TimeoutException;

/**
 * A ROS service on a {@link Ros} connection. Every call ends: with the reply, a
 * {@link ServiceFailedException} (rosbridge reported a failure), a {@link RosTimeoutException}, or a
 * {@link RosException} (the connection dropped). Thread-safe.
 */
public final class Service {
    private final Ros ros;
    private final String name;
    private final String type;

    /**
     * @param ros the connection
     * @param name the service, e.g. {@code /cdra/unlock_filter}
     * @param type the service type, e.g. {@code std_srvs/srv/Trigger}, or null (rosbridge reads
     *     the type from the ROS graph; it is sent for servers that want it)
     */
    public Service(Ros ros, String name, String type) {
        if (name == null || name.isEmpty()) {
            throw new IllegalArgumentException("service name must not be empty");
        }
        this.ros = ros;
        this.name = name;
        this.type = type;
    }

    /** @return the service name */
    public String getName() {
        return name;
    }

    /** @return the service type */
    public String getType() {
        return type;
    }

    /**
     * Calls the service; the future completes with the reply or exceptionally with a
     * {@link RosException} subtype. Waits at most the connection's timeout.
     *
     * @param request the request
     * @return the reply to come
     */
    public CompletableFuture<ServiceResponse> callAsync(ServiceRequest request) {
        return callAsync(request, ros.getOptions().timeout());
    }

    /**
     * @param request the request
     * @param timeout how long to wait for the reply
     * @return the reply to come
     */
    public CompletableFuture<ServiceResponse> callAsync(ServiceRequest request, Duration timeout) {
        return call(Protocol.OP_CALL_SERVICE + ":" + name + ":" + ros.nextId(), request, timeout, timeout);
    }

    /**
     * Sends the call; {@code serverTimeout} goes on the wire so the bridge waits for the ROS
     * service as long as this client does (its own default is shorter than a robot motion).
     */
    private CompletableFuture<ServiceResponse> call(String id, ServiceRequest request, Duration timerTimeout,
            Duration serverTimeout) {
        JsonObject message = new JsonObject();
        message.addProperty(Protocol.FIELD_OP, Protocol.OP_CALL_SERVICE);
        message.addProperty(Protocol.FIELD_ID, id);
        message.addProperty(Protocol.FIELD_SERVICE, name);
        if (type != null) {
            message.addProperty(Protocol.FIELD_TYPE, type);
        }
        message.add(Protocol.FIELD_ARGS, request.toJsonObject());
        message.addProperty(Protocol.FIELD_TIMEOUT, serverTimeout.toNanos() / 1e9);
        return ros.callService(id, name, message, timerTimeout);
    }

    /**
     * jrosbridge's asynchronous call: the callback gets the reply, or a failed response (see
     * {@link ServiceResponse#getResult()}) carrying the reason.
     *
     * @param request the request
     * @param callback receives the outcome once, on the connection's callback thread
     */
    public void callService(ServiceRequest request, ServiceCallback callback) {
        callAsync(request).whenComplete((response, failure) -> ros.dispatch(() -> callback.handleServiceResponse(
                failure == null ? response : ServiceResponse.failure(unwrap(failure).getMessage()))));
    }

    /**
     * Calls and waits at most the connection's timeout.
     *
     * @param request the request
     * @return the reply
     * @throws ServiceFailedException rosbridge reported a failure
     * @throws RosTimeoutException no reply in time
     * @throws RosException the connection dropped or is down
     */
    public ServiceResponse callServiceAndWait(ServiceRequest request) {
        return callServiceAndWait(request, ros.getOptions().timeout());
    }

    /**
     * Calls and waits at most {@code timeout}.
     *
     * @param request the request
     * @param timeout how long to wait for the reply
     * @return the reply
     * @throws ServiceFailedException rosbridge reported a failure
     * @throws RosTimeoutException no reply in time
     * @throws RosException the connection dropped or is down
     */
    public ServiceResponse callServiceAndWait(ServiceRequest request, Duration timeout) {
        return callServiceAndWait(request, timeout, timeout);
    }

    /**
     * Calls and waits at most {@code timeout}, asking the server to wait {@code serverTimeout} for
     * the ROS service: shorter than {@code timeout} on a delayed link, so the server's answer
     * (even a timeout) still reaches this client.
     *
     * @param request the request
     * @param timeout how long to wait for the reply
     * @param serverTimeout how long the server waits for the ROS service
     * @return the reply
     * @throws ServiceFailedException rosbridge reported a failure
     * @throws RosTimeoutException no reply in time
     * @throws RosException the connection dropped or is down
     */
    public ServiceResponse callServiceAndWait(ServiceRequest request, Duration timeout, Duration serverTimeout) {
        String id = Protocol.OP_CALL_SERVICE + ":" + name + ":" + ros.nextId();
        // No timer task: this thread waits with the timeout itself and forgets the call on expiry.
        CompletableFuture<ServiceResponse> reply = call(id, request, null, serverTimeout);
        try {
            return reply.get(timeout.toNanos(), TimeUnit.NANOSECONDS);
        } catch (TimeoutException e) {
            ros.forgetCall(id, timeout);
            if (reply.isDone() && !reply.isCompletedExceptionally()) {
                return reply.join(); // the reply won the race against the timeout
            }
            throw new RosTimeoutException("call_service " + name, timeout);
        } catch (InterruptedException e) {
            ros.forgetCall(id, timeout);
            Thread.currentThread().interrupt();
            throw new RosException("interrupted while calling " + name, e);
        } catch (ExecutionException e) {
            throw unwrap(e);
        }
    }

    private static RosException unwrap(Throwable failure) {
        Throwable cause = failure;
        while ((cause instanceof ExecutionException || cause instanceof java.util.concurrent.CompletionException)
                && cause.getCause() != null) {
            cause = cause.getCause();
        }
        return cause instanceof RosException ros ? ros : new RosException(String.valueOf(cause.getMessage()), cause);
    }
}
