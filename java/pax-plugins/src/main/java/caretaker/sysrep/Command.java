package caretaker.sysrep;

import java.util.Collections;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import java.util.stream.Collectors;

/**
 * A command of a system: what a procedure's command instruction sends.
 *
 * @param id the command id
 * @param label the human-readable name
 * @param args the arguments in declared order
 * @param hazardous whether the command needs confirmation even in autonomous mode
 * @param description free text, or null
 * @param line where the command starts in its file (1-based), 0 if not from a file
 */
public record Command(String id, String label, List<Argument> args, boolean hazardous, String description,
        int line) {
    /** Copies the arguments so the record stays immutable. */
    public Command {
        args = List.copyOf(args);
    }

    /**
     * @param name an argument name
     * @return the argument, or null
     */
    public Argument arg(String name) {
        return args.stream().filter(a -> a.name().equals(name)).findFirst().orElse(null);
    }

    /**
     * Checks a full set of arguments and converts each to its type.
     *
     * @param values argument name → value; every argument must be given, no other
     * @return name → typed value, in declared order, unmodifiable
     * @throws IllegalArgumentException an argument is missing, unknown or does not fit
     */
    public Map<String, Object> checkArguments(Map<String, ?> values) {
        for (String name : values.keySet()) {
            if (arg(name) == null) {
                throw new IllegalArgumentException("command " + PyRepr.of(id) + ": unknown argument "
                        + PyRepr.of(name) + " (expected: " + names() + ")");
            }
        }
        Map<String, Object> typed = new LinkedHashMap<>();
        for (Argument argument : args) {
            if (!values.containsKey(argument.name())) {
                throw new IllegalArgumentException("command " + PyRepr.of(id) + ": missing argument "
                        + PyRepr.of(argument.name()) + " (expected: " + names() + ")");
            }
            try {
                typed.put(argument.name(), argument.check(values.get(argument.name())));
            } catch (IllegalArgumentException e) {
                throw new IllegalArgumentException("command " + PyRepr.of(id) + ": " + e.getMessage(), e);
            }
        }
        return Collections.unmodifiableMap(typed);
    }

    private String names() {
        return args.isEmpty() ? "none" : args.stream().map(Argument::name).collect(Collectors.joining(", "));
    }
}
