package caretaker.rosbridge;

import java.time.Duration;

/** A blocking call got no answer in time. Unlike jrosbridge, no call waits forever. */
public class RosTimeoutException extends RosException {
    private static final long serialVersionUID = 1L;

    /**
     * @param what the call that timed out, e.g. "call_service /x"
     * @param timeout how long it waited
     */
    public RosTimeoutException(String what, Duration timeout) {
        super(what + ": no answer within " + Durations.seconds(timeout) + " s");
    }
}
