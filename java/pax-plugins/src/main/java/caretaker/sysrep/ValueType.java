package caretaker.sysrep;

import java.util.List;

/**
 * The four SysRep value types and the Java type each converts to: string → String,
 * boolean → Boolean, integer → Long, real → Double.
 */
public enum ValueType {
    /** Text. */
    STRING("string"),
    /** true or false. */
    BOOLEAN("boolean"),
    /** A whole number. */
    INTEGER("integer"),
    /** A floating-point number. */
    REAL("real");

    private final String id;

    ValueType(String id) {
        this.id = id;
    }

    /** @return the name used in SysRep files */
    public String id() {
        return id;
    }

    /** @return "string, boolean, integer, real" for messages */
    static String allIds() {
        return "string, boolean, integer, real";
    }

    /**
     * @param id a type name from a SysRep file
     * @return the type, or null if there is none of that name
     */
    public static ValueType byId(String id) {
        for (ValueType type : values()) {
            if (type.id.equals(id)) {
                return type;
            }
        }
        return null;
    }

    /** @return whether min/max apply */
    public boolean isNumeric() {
        return this == INTEGER || this == REAL;
    }

    /**
     * Converts a value to this type, like {@code procedure_language.sysrep.check_value}: strings are accepted
     * for every type (operators type them), so "3" is a valid integer and "true" a valid boolean;
     * a boolean is never taken as a number.
     *
     * @param name what the value is, for the message
     * @param value the value
     * @param minimum the least allowed value, or null
     * @param maximum the largest allowed value, or null
     * @param allowed the allowed values (already of this type), or null
     * @return the value as this type's Java type
     * @throws IllegalArgumentException the value does not fit, saying why
     */
    public Object check(String name, Object value, Number minimum, Number maximum, List<?> allowed) {
        Object converted = convert(name, value);
        if (minimum != null && ((Number) converted).doubleValue() < minimum.doubleValue()) {
            throw new IllegalArgumentException(name + ": " + PyRepr.of(converted) + " is below the minimum "
                    + PyRepr.of(minimum));
        }
        if (maximum != null && ((Number) converted).doubleValue() > maximum.doubleValue()) {
            throw new IllegalArgumentException(name + ": " + PyRepr.of(converted) + " is above the maximum "
                    + PyRepr.of(maximum));
        }
        if (allowed != null && allowed.stream().noneMatch(a -> sameValue(a, converted))) {
            throw new IllegalArgumentException(name + ": " + PyRepr.of(converted) + " is not one of "
                    + PyRepr.of(allowed));
        }
        return converted;
    }

    /**
     * @param name what the value is, for the message
     * @param value the value
     * @return the value as this type's Java type
     * @throws IllegalArgumentException the value does not fit
     */
    public Object check(String name, Object value) {
        return check(name, value, null, null, null);
    }

    private static boolean sameValue(Object a, Object b) {
        if (a instanceof Number x && b instanceof Number y) {
            return x.doubleValue() == y.doubleValue();
        }
        return a.equals(b);
    }

    private Object convert(String name, Object value) {
        switch (this) {
            case STRING:
                if (!(value instanceof String)) {
                    throw new IllegalArgumentException(name + ": expected string, got " + PyRepr.typeName(value) + " "
                            + PyRepr.of(value));
                }
                return value;
            case BOOLEAN:
                if (value instanceof Boolean) {
                    return value;
                }
                if (value instanceof String text) {
                    String word = text.strip().toLowerCase(java.util.Locale.ROOT);
                    if (word.equals("true") || word.equals("false")) {
                        return word.equals("true");
                    }
                }
                throw new IllegalArgumentException(name + ": expected boolean (true/false), got " + PyRepr.of(value));
            case INTEGER:
                return toInteger(name, value);
            default:
                return toReal(name, value);
        }
    }

    private static Long toInteger(String name, Object value) {
        IllegalArgumentException wrong = new IllegalArgumentException(name + ": expected integer, got "
                + PyRepr.of(value));
        if (value instanceof Double || value instanceof Float) {
            double real = ((Number) value).doubleValue();
            if (real != Math.rint(real) || Double.isInfinite(real)) {
                throw wrong;
            }
            return (long) real;
        }
        if (value instanceof Number number && !(value instanceof Boolean)) {
            return number.longValue();
        }
        if (value instanceof String text) {
            try {
                return Long.parseLong(text.strip().replace("_", ""));
            } catch (NumberFormatException e) {
                throw wrong;
            }
        }
        throw wrong;
    }

    private static Double toReal(String name, Object value) {
        IllegalArgumentException wrong = new IllegalArgumentException(name + ": expected real, got "
                + PyRepr.of(value));
        if (value instanceof Number number) {
            return number.doubleValue();
        }
        if (value instanceof String text) {
            String word = text.strip().toLowerCase(java.util.Locale.ROOT);
            switch (word) {
                case "inf", "+inf", "infinity", "+infinity":
                    return Double.POSITIVE_INFINITY;
                case "-inf", "-infinity":
                    return Double.NEGATIVE_INFINITY;
                case "nan", "+nan", "-nan":
                    return Double.NaN;
                default:
                    break;
            }
            if (word.matches("[+-]?(\\d[\\d_]*\\.?[\\d_]*|\\.\\d[\\d_]*)(e[+-]?\\d+)?")) {
                return Double.parseDouble(word.replace("_", ""));
            }
        }
        throw wrong;
    }
}
