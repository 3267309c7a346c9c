package caretaker.rosbridge;

import com.google.gson.JsonObject;

/**
 * A ROS 2 {@code std_msgs/Header}: stamp and frame, and no {@code seq} (ROS 2 removed it and
 * rosbridge rejects it, which broke jrosbridge's ROS 1 Header).
 *
 * @param stamp when the data was valid
 * @param frameId the frame the data is expressed in
 */
public record Header(Time stamp, String frameId) {
    /**
     * @param frameId the frame
     * @return a header stamped now
     */
    public static Header now(String frameId) {
        return new Header(Time.now(), frameId);
    }

    /** @return {@code {"stamp": {...}, "frame_id": ...}} */
    public JsonObject toJson() {
        JsonObject json = new JsonObject();
        json.add("stamp", stamp.toJson());
        json.addProperty("frame_id", frameId);
        return json;
    }
}
