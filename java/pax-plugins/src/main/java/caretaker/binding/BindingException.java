package caretaker.binding;

/** A binding file is malformed; the message names the file, the entry and what to fix. */
public class BindingException extends RuntimeException {
    private static final long serialVersionUID = 1L;

    /** @param message {@code file: where: problem} */
    public BindingException(String message) {
        super(message);
    }

    /**
     * @param message {@code file: where: problem}
     * @param cause the underlying failure
     */
    public BindingException(String message, Throwable cause) {
        super(message, cause);
    }
}
