package caretaker.rosbridge;

import com.google.gson.JsonObject;
import com.google.gson.JsonParser;

/**
 * An immutable JSON object: messages, requests and responses. The wrapped object is copied on the
 * way in and on the way out, so no caller can change a message another thread is reading.
 */
public abstract class JsonWrapper {
    private final JsonObject json;

    /** @param json the object to wrap (copied) */
    protected JsonWrapper(JsonObject json) {
        this.json = json.deepCopy();
    }

    /** @param json JSON text of an object */
    protected JsonWrapper(String json) {
        this(parseObject(json));
    }

    private static JsonObject parseObject(String text) {
        try {
            return JsonParser.parseString(text).getAsJsonObject();
        } catch (RuntimeException e) {
            throw new IllegalArgumentException("not a JSON object: " + text, e);
        }
    }

    /** @return a copy of the wrapped JSON object */
    public JsonObject toJsonObject() {
        return json.deepCopy();
    }

    /** Reads without copying, for this package's own serialisation. */
    JsonObject json() {
        return json;
    }

    /** @return the JSON text */
    @Override
    public String toString() {
        return json.toString();
    }

    @Override
    public boolean equals(Object other) {
        return other != null && other.getClass() == getClass() && ((JsonWrapper) other).json.equals(json);
    }

    @Override
    public int hashCode() {
        return json.hashCode();
    }
}
