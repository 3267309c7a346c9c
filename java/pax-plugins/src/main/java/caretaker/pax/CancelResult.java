package caretaker.pax;

/**
 * What a system answered to a cancel of a command in flight (a halt).
 *
 * @param stopped whether the system confirmed the command stopped (or that nothing was running);
 *     false when the plugin's commands cannot be cancelled, or the cancel did not reach the system
 * @param message what the system said, or why the command could not be cancelled
 */
public record CancelResult(boolean stopped, String message) {
    /** Requires a message: a cancel always says what it did. */
    public CancelResult {
        if (message == null || message.isEmpty()) {
            throw new IllegalArgumentException("a cancel result must say what happened");
        }
    }
}
