package caretaker.rosbridge;

/**
 * A message was not sent because the connection is down: the server cannot have received it.
 * (Any other {@link RosException} from a send may come after the server got the message.)
 */
public class NotConnectedException extends RosException {
    private static final long serialVersionUID = 1L;

    /** @param message which server */
    public NotConnectedException(String message) {
        super(message);
    }
}
