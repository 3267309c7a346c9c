package caretaker.rosbridge;

import com.google.gson.JsonObject;

/**
 * A ROS {@code geometry_msgs/Pose}: position and unit quaternion.
 *
 * @param x position x in metres
 * @param y position y in metres
 * @param z position z in metres
 * @param qx quaternion x
 * @param qy quaternion y
 * @param qz quaternion z
 * @param qw quaternion w
 */
public record Pose(double x, double y, double z, double qx, double qy, double qz, double qw) {
    /**
     * A pose from position and roll/pitch/yaw about the fixed axes X, then Y, then Z (the ROS
     * convention, as tf's {@code quaternion_from_euler(roll, pitch, yaw)}).
     *
     * @param x position x
     * @param y position y
     * @param z position z
     * @param roll rotation about X in radians
     * @param pitch rotation about Y in radians
     * @param yaw rotation about Z in radians
     * @return the pose
     */
    public static Pose fromRpy(double x, double y, double z, double roll, double pitch, double yaw) {
        double cr = Math.cos(roll / 2);
        double sr = Math.sin(roll / 2);
        double cp = Math.cos(pitch / 2);
        double sp = Math.sin(pitch / 2);
        double cy = Math.cos(yaw / 2);
        double sy = Math.sin(yaw / 2);
        return new Pose(x, y, z,
                sr * cp * cy - cr * sp * sy,
                cr * sp * cy + sr * cp * sy,
                cr * cp * sy - sr * sp * cy,
                cr * cp * cy + sr * sp * sy);
    }

    /**
     * Reads a {@code geometry_msgs/Pose} JSON object (missing fields are zero, w one).
     *
     * @param json {@code {"position": {x,y,z}, "orientation": {x,y,z,w}}}
     * @return the pose
     */
    public static Pose fromJson(JsonObject json) {
        JsonObject position = json.has("position") ? json.getAsJsonObject("position") : new JsonObject();
        JsonObject orientation = json.has("orientation") ? json.getAsJsonObject("orientation") : new JsonObject();
        return new Pose(number(position, "x", 0), number(position, "y", 0), number(position, "z", 0),
                number(orientation, "x", 0), number(orientation, "y", 0), number(orientation, "z", 0),
                number(orientation, "w", 1));
    }

    private static double number(JsonObject json, String key, double missing) {
        return json.has(key) ? json.get(key).getAsDouble() : missing;
    }

    /** @return {@code [x, y, z, roll, pitch, yaw]}, the inverse of {@link #fromRpy} */
    public java.util.List<Double> toXyzRpy() {
        double roll = Math.atan2(2 * (qw * qx + qy * qz), 1 - 2 * (qx * qx + qy * qy));
        double pitch = Math.asin(Math.max(-1, Math.min(1, 2 * (qw * qy - qz * qx))));
        double yaw = Math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz));
        return java.util.List.of(x, y, z, roll, pitch, yaw);
    }

    /** @return the identity pose at the origin */
    public static Pose identity() {
        return new Pose(0, 0, 0, 0, 0, 0, 1);
    }

    /** @return {@code {"position": {x,y,z}, "orientation": {x,y,z,w}}} */
    public JsonObject toJson() {
        JsonObject position = new JsonObject();
        position.addProperty("x", x);
        position.addProperty("y", y);
        position.addProperty("z", z);
        JsonObject orientation = new JsonObject();
        orientation.addProperty("x", qx);
        orientation.addProperty("y", qy);
        orientation.addProperty("z", qz);
        orientation.addProperty("w", qw);
        JsonObject json = new JsonObject();
        json.add("position", position);
        json.add("orientation", orientation);
        return json;
    }

    /**
     * @param header the frame and stamp
     * @return a {@code geometry_msgs/PoseStamped} with this pose
     */
    public JsonObject toStampedJson(Header header) {
        JsonObject json = new JsonObject();
        json.add("header", header.toJson());
        json.add("pose", toJson());
        return json;
    }
}
