package caretaker.rosbridge;

import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import java.time.Instant;

/**
 * A ROS 2 {@code builtin_interfaces/Time}: {@code {"sec": ..., "nanosec": ...}}. Reads the ROS 1
 * spelling {@code secs/nsecs} too, because old clients and servers still send it.
 *
 * @param sec whole seconds since the epoch
 * @param nanosec nanoseconds within the second, 0..999999999
 */
public record Time(long sec, long nanosec) {
    /** Checks the nanoseconds are within one second. */
    public Time {
        if (nanosec < 0 || nanosec > 999_999_999L) {
            throw new IllegalArgumentException("nanosec must be within 0..999999999, got " + nanosec);
        }
    }

    /** @return the current wall-clock time */
    public static Time now() {
        return of(Instant.now());
    }

    /**
     * @param instant a point in time
     * @return the same time as a ROS time
     */
    public static Time of(Instant instant) {
        return new Time(instant.getEpochSecond(), instant.getNano());
    }

    /**
     * @param json {@code {sec, nanosec}} or {@code {secs, nsecs}}
     * @return the time it holds
     * @throws IllegalArgumentException it is not a time
     */
    public static Time fromJson(JsonElement json) {
        if (json == null || !json.isJsonObject()) {
            throw new IllegalArgumentException("a time must be an object {sec, nanosec}, got " + json);
        }
        JsonObject object = json.getAsJsonObject();
        JsonElement sec = object.has("sec") ? object.get("sec") : object.get("secs");
        JsonElement nanosec = object.has("nanosec") ? object.get("nanosec") : object.get("nsecs");
        if (sec == null || nanosec == null) {
            throw new IllegalArgumentException("a time needs sec and nanosec, got " + json);
        }
        return new Time(sec.getAsLong(), nanosec.getAsLong());
    }

    /** @return {@code {"sec": ..., "nanosec": ...}} */
    public JsonObject toJson() {
        JsonObject json = new JsonObject();
        json.addProperty("sec", sec);
        json.addProperty("nanosec", nanosec);
        return json;
    }

    /** @return whether this is the zero time ROS uses for "not set" */
    public boolean isZero() {
        return sec == 0 && nanosec == 0;
    }

    /** @return the same time as an Instant */
    public Instant toInstant() {
        return Instant.ofEpochSecond(sec, nanosec);
    }
}
