package caretaker.rosbridge;

/**
 * The server answered a service call with {@code result: false}: the service does not exist, its
 * server died, it timed out on the server, or the arguments did not fit its type. The message is
 * the server's text (rosbridge sends it as the string {@code values}).
 */
public class ServiceFailedException extends RosException {
    private static final long serialVersionUID = 1L;
    private final String service;
    private final String reason;

    /**
     * @param service the service that was called
     * @param reason the server's description of the failure
     */
    public ServiceFailedException(String service, String reason) {
        super("service " + service + " failed: " + reason);
        this.service = service;
        this.reason = reason;
    }

    /** @return the service that was called */
    public String getService() {
        return service;
    }

    /** @return the server's description of the failure */
    public String getReason() {
        return reason;
    }
}
