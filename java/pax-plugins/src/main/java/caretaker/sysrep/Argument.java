package caretaker.sysrep;

import java.util.List;

/**
 * A typed argument of a command, with optional limits used for validation and forms.
 *
 * @param name the argument name
 * @param type the value type
 * @param units units for display, or null
 * @param min least allowed value, or null
 * @param max largest allowed value, or null
 * @param allowed the allowed values (the SysRep's {@code enum}), or null
 * @param description free text, or null
 */
public record Argument(String name, ValueType type, String units, Number min, Number max, List<Object> allowed,
        String description) {
    /** Copies the allowed values so the record stays immutable. */
    public Argument {
        allowed = allowed == null ? null : List.copyOf(allowed);
    }

    /**
     * @param name the argument name
     * @param type the value type
     */
    public Argument(String name, ValueType type) {
        this(name, type, null, null, null, null, null);
    }

    /**
     * @param value a value for this argument
     * @return the value converted to this argument's type
     * @throws IllegalArgumentException it does not fit, saying why
     */
    public Object check(Object value) {
        return type.check(name, value, min, max, allowed);
    }
}
