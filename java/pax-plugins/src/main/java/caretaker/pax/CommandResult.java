package caretaker.pax;

import java.util.Collections;
import java.util.LinkedHashMap;
import java.util.Map;

/**
 * The outcome of a command as the system reported it. A plugin never reports success it did not
 * observe: a refused or failed call is {@code success == false} with the system's message.
 *
 * @param success whether the system carried the command out
 * @param message the system's message (why it failed, or what it did)
 * @param values named result values (strings, booleans, longs, doubles), possibly empty
 */
public record CommandResult(boolean success, String message, Map<String, Object> values) {
    /** Copies the values, keeping their order, so the record stays immutable. */
    public CommandResult {
        message = message == null ? "" : message;
        values = Collections.unmodifiableMap(new LinkedHashMap<>(values));
    }

    /**
     * @param message what was done
     * @param values result values
     * @return a successful result
     */
    public static CommandResult success(String message, Map<String, Object> values) {
        return new CommandResult(true, message, values);
    }

    /**
     * @param message why it failed
     * @return a failed result without values
     */
    public static CommandResult failure(String message) {
        return new CommandResult(false, message, Map.of());
    }
}
