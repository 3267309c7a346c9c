package caretaker.rosbridge;

import com.google.gson.JsonElement;
import com.google.gson.JsonPrimitive;

/** Plain Java values of rosbridge JSON fields, as plugins hand them to PAX. */
public final class JsonValues {
    /** Doubles hold integers exactly up to 2^53; larger "integral" values stay doubles. */
    private static final double EXACT_INTEGERS = 1e15;

    private JsonValues() {
    }

    /**
     * @param field a message field, or null when the message lacks it
     * @return Boolean for a boolean; Long for an integral number (JSON does not say int or
     *     float, and ROS integers arrive as {@code 3}, not {@code 3.0}); Double for another
     *     number; String for a string; the JSON text of an array or object; null for null
     */
    public static Object plain(JsonElement field) {
        if (field == null || field.isJsonNull()) {
            return null;
        }
        if (!field.isJsonPrimitive()) {
            return field.toString();
        }
        JsonPrimitive primitive = field.getAsJsonPrimitive();
        if (primitive.isBoolean()) {
            return primitive.getAsBoolean();
        }
        if (primitive.isNumber()) {
            double number = primitive.getAsDouble();
            return number == Math.rint(number) && Math.abs(number) < EXACT_INTEGERS ? (Object) primitive.getAsLong()
                    : (Object) number;
        }
        return primitive.getAsString();
    }
}
