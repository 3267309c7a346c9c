/**
 * A rosbridge v2 client in the shape of jrosbridge ({@link caretaker.rosbridge.Ros},
 * {@link caretaker.rosbridge.Topic}, {@link caretaker.rosbridge.Service}, message wrappers and
 * one-method callbacks), fixing what hurt jrosbridge's users: every blocking call takes a timeout
 * and throws {@link caretaker.rosbridge.RosTimeoutException}; a failed service call (rosbridge
 * sends {@code values} as a string) becomes a {@link caretaker.rosbridge.ServiceFailedException};
 * the connection reconnects by itself and re-sends subscriptions and advertisements; state is
 * thread-safe; fragments are reassembled; time and headers follow ROS 2 ({@code sec/nanosec}, no
 * {@code seq}).
 *
 * <p>Threads: one WebSocket reader thread per {@link caretaker.rosbridge.Ros}, which never runs
 * user code; topic and service callbacks run in order on one callback thread per {@code Ros}, so a
 * callback may itself make blocking calls.
 */
package caretaker.rosbridge;
