package caretaker.rosbridge;

/** Receives the reply of an asynchronous service call. */
@FunctionalInterface
public interface ServiceCallback {
    /**
     * Called on the connection's callback thread exactly once per call: with the reply, or with a
     * failed response (see {@link ServiceResponse#getResult()}) when rosbridge reported a failure,
     * the connection was lost or the call timed out.
     *
     * @param response the reply
     */
    void handleServiceResponse(ServiceResponse response);
}
