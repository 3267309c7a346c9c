package caretaker.pax;

import caretaker.rosbridge.LedgerAnswer;
import java.util.Collections;
import java.util.LinkedHashMap;
import java.util.Map;

/**
 * The outcome of a command as the system reported it. A plugin never reports success or failure
 * it did not learn from the system: a command whose reply was lost and could not be learnt is
 * {@link Outcome#UNKNOWN}, never a failure, and a command never sent is a failure that says so.
 * Every outcome but SUCCEEDED carries a message saying why.
 *
 * @param outcome what became of the command
 * @param message the system's message (why it failed, or what it did), or why the outcome is
 *     not known
 * @param values named result values (strings, booleans, longs, doubles), possibly empty
 */
public record CommandResult(Outcome outcome, String message, Map<String, Object> values) {
    /** Copies the values, keeping their order, so the record stays immutable; requires a reason. */
    public CommandResult {
        message = message == null ? "" : message;
        if (outcome != Outcome.SUCCEEDED && message.isEmpty()) {
            throw new IllegalArgumentException("a " + outcome + " result must say why");
        }
        values = Collections.unmodifiableMap(new LinkedHashMap<>(values));
    }

    /** @return whether the system carried the command out (only {@link Outcome#SUCCEEDED}) */
    public boolean success() {
        return outcome == Outcome.SUCCEEDED;
    }

    /**
     * @param message what was done
     * @param values result values
     * @return a successful result
     */
    public static CommandResult success(String message, Map<String, Object> values) {
        return new CommandResult(Outcome.SUCCEEDED, message, values);
    }

    /**
     * @param message why it failed
     * @return a failed result without values
     */
    public static CommandResult failure(String message) {
        return new CommandResult(Outcome.FAILED, message, Map.of());
    }

    /**
     * @param message why the outcome is not known
     * @return a result of unknown outcome
     */
    public static CommandResult unknown(String message) {
        return new CommandResult(Outcome.UNKNOWN, message, Map.of());
    }

    /**
     * The result of a ledger answer that carries no reply of the system: UNKNOWN stays UNKNOWN, a
     * command never executed is a failure saying so.
     *
     * @param commandId the command, for the message
     * @param answer an answer whose {@link LedgerAnswer#response()} is null
     * @return the result
     */
    public static CommandResult withoutReply(String commandId, LedgerAnswer answer) {
        return switch (answer.state()) {
            case REFUSED -> failure(commandId + ": not executed: " + answer.message());
            default -> unknown(commandId + ": outcome unknown: " + answer.message());
        };
    }
}
