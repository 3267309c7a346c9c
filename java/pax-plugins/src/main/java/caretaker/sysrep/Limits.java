package caretaker.sysrep;

import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import java.util.Set;
import java.util.regex.Matcher;
import java.util.regex.Pattern;

/**
 * A telemetry item's limits, as a SysRep declares them: red and yellow bands of a number, or a value
 * that must hold, with how long a value must stay out (samples in a row, or seconds). The plugins do
 * not act on limits (procedures' monitors do, in PAX); the loader checks them as the Python loader
 * does, with the same words, so a SysRep is valid on both sides or on neither.
 *
 * @param redLow below it: red, or null
 * @param yellowLow below it: yellow, or null
 * @param yellowHigh above it: yellow, or null
 * @param redHigh above it: red, or null
 * @param equals the value that must hold (then there are no bands), or null
 * @param persistenceSamples samples in a row a value must stay out (1 when seconds are given)
 * @param persistenceSeconds seconds a value must stay out (0 when samples are given)
 */
public record Limits(Double redLow, Double yellowLow, Double yellowHigh, Double redHigh, Object equals,
        int persistenceSamples, double persistenceSeconds) {

    private static final List<String> BANDS = List.of("red_low", "yellow_low", "yellow_high", "red_high");
    private static final Set<String> KEYS = Set.of("red_low", "yellow_low", "yellow_high", "red_high", "equals",
            "persistence");
    private static final Pattern PERSISTENCE = Pattern.compile("^\\s*(\\d+(?:\\.\\d*)?)\\s*(s)?\\s*$");

    /**
     * The limits a SysRep's {@code limits:} mapping states for an item of {@code type}.
     *
     * @throws IllegalArgumentException saying what is wrong, in the Python loader's words
     */
    static Limits parse(Object data, ValueType type) {
        if (!(data instanceof Map<?, ?> map)) {
            throw new IllegalArgumentException("limits must be a mapping (" + String.join(", ", BANDS)
                    + " or equals), got " + PyRepr.of(data));
        }
        List<String> unknown = new ArrayList<>();
        for (Object key : map.keySet()) {
            if (!(key instanceof String name) || !KEYS.contains(name)) {
                unknown.add(String.valueOf(key));
            }
        }
        if (!unknown.isEmpty()) {
            unknown.sort(null);
            throw new IllegalArgumentException("limits: unknown key " + PyRepr.of(unknown.get(0)) + " (allowed: "
                    + String.join(", ", BANDS) + ", equals, persistence)");
        }
        int samples = 1;
        double seconds = 0;
        if (map.containsKey("persistence")) {
            double[] persistence = persistence(map.get("persistence"));
            samples = (int) persistence[0];
            seconds = persistence[1];
        }
        if (map.containsKey("equals")) {
            if (BANDS.stream().anyMatch(map::containsKey)) {
                throw new IllegalArgumentException("limits: equals or the bands (red_low ... red_high), not both");
            }
            return new Limits(null, null, null, null, type.check("equals", map.get("equals")), samples, seconds);
        }
        if (!type.isNumeric()) {
            throw new IllegalArgumentException("limits: bands apply to integer or real items; a " + type.id()
                    + " item states equals");
        }
        Map<String, Double> bands = new LinkedHashMap<>();
        for (String key : BANDS) {
            if (map.containsKey(key)) {
                Object value = map.get(key);
                if (!(value instanceof Number number) || value instanceof Boolean
                        || !Double.isFinite(number.doubleValue())) {
                    throw new IllegalArgumentException("limits: " + key + " must be a finite number, got "
                            + PyRepr.of(value));
                }
                bands.put(key, number.doubleValue());
            }
        }
        if (bands.isEmpty()) {
            throw new IllegalArgumentException(
                    "limits: state at least one of red_low, yellow_low, yellow_high, red_high, or equals");
        }
        List<Double> ordered = new ArrayList<>(bands.values());
        List<Double> sorted = new ArrayList<>(ordered);
        sorted.sort(null);
        if (!ordered.equals(sorted)) {
            throw new IllegalArgumentException("limits must rise: red_low < yellow_low <= yellow_high < red_high, got "
                    + PyRepr.of(bands));
        }
        return new Limits(bands.get("red_low"), bands.get("yellow_low"), bands.get("yellow_high"),
                bands.get("red_high"), null, samples, seconds);
    }

    /** {samples, seconds} of a persistence: {@code 3} (samples in a row) or {@code "2 s"}. */
    private static double[] persistence(Object value) {
        String expected = "persistence must be a number of samples (3) or seconds (2 s), got ";
        if (value instanceof Boolean) {
            throw new IllegalArgumentException(expected + PyRepr.of(value));
        }
        if (value instanceof Integer || value instanceof Long) {
            long samples = ((Number) value).longValue();
            if (samples >= 1) {
                return new double[] {samples, 0};
            }
        }
        Matcher found = PERSISTENCE.matcher(String.valueOf(value));
        if (!found.matches()) {
            throw new IllegalArgumentException(expected + PyRepr.of(value));
        }
        double number = Double.parseDouble(found.group(1));
        if (found.group(2) != null) {
            if (!Double.isFinite(number) || number <= 0) {
                throw new IllegalArgumentException("persistence in seconds must be more than 0, got "
                        + PyRepr.of(value));
            }
            return new double[] {1, number};
        }
        if (number != Math.floor(number) || number < 1) {
            throw new IllegalArgumentException("persistence in samples must be a whole number of 1 or more, got "
                    + PyRepr.of(value));
        }
        return new double[] {number, 0};
    }
}
