package caretaker.rosbridge;

/**
 * The bridge refused this client's authentication (it closed the connection with 1008). The
 * connection does not reconnect by itself: the secret or token is wrong, and trying again with
 * the same one cannot help.
 */
public class RosAuthException extends RosException {
    private static final long serialVersionUID = 1L;

    /** @param message who refused and the bridge's reason */
    public RosAuthException(String message) {
        super(message);
    }
}
