package caretaker.rosbridge;

/** What the habitat's command ledger says became of a command key (caretaker_ledger_msgs). */
public enum LedgerState {
    /** The service answered, and its {@code success} field (if any) was not false. */
    SUCCEEDED,
    /** The service answered with {@code success} false. */
    FAILED,
    /** It may or may not have executed; nobody can tell any more. Never to be taken for either. */
    UNKNOWN,
    /** Never executed: the request could not be made, or was never sent. */
    REFUSED,
    /** Running now (only from {@link CommandLedger#outcome}). */
    IN_PROGRESS,
    /** The ledger has no record of the key (only from {@link CommandLedger#outcome}). */
    NOT_FOUND
}
