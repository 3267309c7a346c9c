package caretaker.pax;

/**
 * A plugin could not do what was asked for a reason other than the system refusing: an unknown
 * command or item, an ambiguous template, a bad binding option, a lost connection.
 */
public class PluginException extends RuntimeException {
    private static final long serialVersionUID = 1L;

    /** @param message what went wrong and what to fix */
    public PluginException(String message) {
        super(message);
    }

    /**
     * @param message what went wrong
     * @param cause the underlying failure
     */
    public PluginException(String message, Throwable cause) {
        super(message, cause);
    }
}
