package caretaker.rosbridge;

/**
 * The habitat has no command ledger (its services do not exist there), and this connection may
 * not do without one: the binding states a link, so every command must be executed at most once
 * and its outcome learnt across outages, which only the ledger can do.
 */
public class LedgerMissingException extends RosException {
    private static final long serialVersionUID = 1L;

    /** @param message where no ledger answered and what to do */
    public LedgerMissingException(String message) {
        super(message);
    }
}
