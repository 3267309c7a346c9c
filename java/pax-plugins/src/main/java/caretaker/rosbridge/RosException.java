package caretaker.rosbridge;

/** Something went wrong talking to a rosbridge server; the message says what and where. */
public class RosException extends RuntimeException {
    private static final long serialVersionUID = 1L;

    /**
     * @param message what went wrong, naming the server, topic or service concerned
     */
    public RosException(String message) {
        super(message);
    }

    /**
     * @param message what went wrong
     * @param cause the underlying failure
     */
    public RosException(String message, Throwable cause) {
        super(message, cause);
    }
}
