package caretaker.pax;

import java.time.Duration;
import java.util.Collections;
import java.util.LinkedHashMap;
import java.util.Map;
import java.util.Set;
import java.util.TreeSet;

/**
 * The {@code options} of a binding entry, read with typed getters whose errors name the option
 * and the binding file.
 */
public final class PluginOptions {
    private final Map<String, Object> values;
    private final String where;

    /**
     * @param values option name → value as read from YAML
     * @param where the binding entry, for messages (e.g. {@code bindings/iva.yaml: systems[0]})
     */
    public PluginOptions(Map<String, ?> values, String where) {
        this.values = Collections.unmodifiableMap(new LinkedHashMap<>(values));
        this.where = where;
    }

    /**
     * @param plugins the plugins sharing these options
     * @param known the options those plugins understand together
     * @throws PluginException an option is unknown (likely a typo)
     */
    public void requireKnown(String plugins, Set<String> known) {
        for (String key : values.keySet()) {
            if (!known.contains(key)) {
                throw new PluginException(where + ": no option '" + key + "' for " + plugins + " (options: "
                        + String.join(", ", new TreeSet<>(known)) + ")");
            }
        }
    }

    /**
     * @param key an option given in seconds
     * @param fallback used when the option is absent
     * @return the duration
     * @throws PluginException the value is not a positive number
     */
    public Duration seconds(String key, Duration fallback) {
        Object value = values.get(key);
        if (value == null) {
            return fallback;
        }
        if (!(value instanceof Number number) || number.doubleValue() <= 0) {
            throw new PluginException(where + ": option '" + key + "' must be a positive number of seconds, got "
                    + value);
        }
        return Duration.ofNanos((long) (number.doubleValue() * 1e9));
    }

    /**
     * @param key an option holding text
     * @param fallback used when absent
     * @return the text
     * @throws PluginException the value is not a string
     */
    public String string(String key, String fallback) {
        Object value = values.get(key);
        if (value == null) {
            return fallback;
        }
        if (!(value instanceof String text)) {
            throw new PluginException(where + ": option '" + key + "' must be a string, got " + value);
        }
        return text;
    }

    /**
     * @param key an option holding a mapping of names to strings
     * @return the mapping, empty when absent
     * @throws PluginException the value is not such a mapping
     */
    public Map<String, String> stringMap(String key) {
        Object value = values.get(key);
        if (value == null) {
            return Map.of();
        }
        if (!(value instanceof Map<?, ?> map)) {
            throw new PluginException(where + ": option '" + key + "' must be a mapping of names to strings, got "
                    + value);
        }
        Map<String, String> out = new LinkedHashMap<>();
        for (Map.Entry<?, ?> entry : map.entrySet()) {
            if (!(entry.getKey() instanceof String name) || !(entry.getValue() instanceof String text)) {
                throw new PluginException(where + ": option '" + key + "' must map names to strings, got "
                        + entry.getKey() + ": " + entry.getValue());
            }
            out.put(name, text);
        }
        return Collections.unmodifiableMap(out);
    }

    /** @return where these options were written, for messages */
    public String where() {
        return where;
    }
}
