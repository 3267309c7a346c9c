package caretaker.rosbridge;

import java.time.Duration;
import java.time.Instant;
import java.util.concurrent.Executors;
import java.util.concurrent.ScheduledExecutorService;
import java.util.concurrent.TimeUnit;
import java.util.function.Consumer;

/**
 * Keeps a connection honest: pings it every interval and reports it silent when nothing (no
 * frame, no pong) came from the server for longer than the timeout. Its own thread, because a
 * ping may wait behind a send on a slow link.
 */
final class Keepalive implements AutoCloseable {
    private final ScheduledExecutorService thread;
    private final long timeoutNanos;
    private final Runnable ping;
    private final Consumer<Instant> silent;
    private volatile long heardNanos = System.nanoTime();
    private volatile Instant heardAt = Instant.now();

    /**
     * @param name the thread's name
     * @param interval how often to ping
     * @param timeout how long the server may stay silent
     * @param ping sends one ping (runs on this thread)
     * @param silent told the time the server was last heard when it stayed silent too long
     */
    Keepalive(String name, Duration interval, Duration timeout, Runnable ping, Consumer<Instant> silent) {
        this.timeoutNanos = timeout.toNanos();
        this.ping = ping;
        this.silent = silent;
        this.thread = Executors.newSingleThreadScheduledExecutor(runnable -> {
            Thread worker = new Thread(runnable, name);
            worker.setDaemon(true);
            return worker;
        });
        thread.scheduleWithFixedDelay(this::tick, interval.toNanos(), interval.toNanos(), TimeUnit.NANOSECONDS);
    }

    /** Something came from the server (or a new connection opened): it is alive now. */
    void heard() {
        heardNanos = System.nanoTime();
        heardAt = Instant.now();
    }

    /** @return {@link System#nanoTime()} when the server was last heard */
    long lastHeardNanos() {
        return heardNanos;
    }

    /** @return when the server was last heard */
    Instant lastHeard() {
        return heardAt;
    }

    private void tick() {
        if (System.nanoTime() - heardNanos > timeoutNanos) {
            silent.accept(heardAt);
        } else {
            ping.run();
        }
    }

    @Override
    public void close() {
        thread.shutdownNow();
    }
}
