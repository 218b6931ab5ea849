// MoM Localizer client for Unity: one GameObject per tracked person, moved from the daemon's
// WebSocket stream (WS /v1/stream, snapshot schema version 1).
//
// Usage: add this component to any GameObject in the scene, set `Url` (and `Token` if the daemon
// has one), optionally assign a `PersonPrefab` (a capsule is created otherwise). Floor coordinates
// (x, y) in metres map to Unity (x, 0, y) * Scale + Origin (Unity is y-up, 1 unit = 1 metre).
//
// Design:
// - The socket runs on a background task (System.Net.WebSockets.ClientWebSocket); Unity objects
//   may only be touched on the main thread, so the task stores only the newest snapshot (a
//   latest-value slot under a lock) and Update() applies it. A slow frame skips snapshots instead
//   of queueing them.
// - Reconnects with exponential back-off (0.5 s doubling to MaxBackoffSeconds); close code 4401
//   (token rejected) stops retrying and logs an error.
// - Messages are parsed with JsonUtility (no package needed); fragments are reassembled.
// - A person missing from the stream for DespawnSeconds is destroyed; motion is smoothed.
//
// Not for WebGL builds (ClientWebSocket is unavailable there).

using System;
using System.Collections.Generic;
using System.IO;
using System.Net.WebSockets;
using System.Text;
using System.Threading;
using System.Threading.Tasks;
using UnityEngine;

public class MoMLocalizerClient : MonoBehaviour
{
    [Serializable]
    public class Person
    {
        public int id;
        public float x;
        public float y;
        public float vx;
        public float vy;
        public float confidence;
        public int[] cameras;
    }

    [Serializable]
    public class Snapshot
    {
        public int v;
        public long seq;
        public double t;
        public Person[] people;
    }

    [Tooltip("Daemon stream URL, e.g. ws://192.168.1.20:8765/v1/stream")]
    public string Url = "ws://127.0.0.1:8765/v1/stream";

    [Tooltip("API token (leave empty when the daemon has none)")]
    public string Token = "";

    [Tooltip("Spawned once per person id; a capsule when empty")]
    public GameObject PersonPrefab;

    public Vector3 Origin = Vector3.zero;
    public float Scale = 1f;

    [Tooltip("Position smoothing rate (1/s); 0 = jump to each new position")]
    public float Smoothing = 15f;

    public float DespawnSeconds = 2f;
    public float MaxBackoffSeconds = 10f;

    [Tooltip("Hide people below this confidence (coasting tracks fade towards 0)")]
    public float MinConfidence = 0f;

    public bool Connected { get; private set; }
    public long LastSeq { get; private set; }

    private readonly object _lock = new object();
    private Snapshot _latest;
    private CancellationTokenSource _cancel;
    private readonly Dictionary<int, GameObject> _objects = new Dictionary<int, GameObject>();
    private readonly Dictionary<int, Vector3> _targets = new Dictionary<int, Vector3>();
    private readonly Dictionary<int, float> _lastSeen = new Dictionary<int, float>();

    private void OnEnable()
    {
        _cancel = new CancellationTokenSource();
        var token = _cancel.Token;
        Task.Run(() => ReceiveLoop(token));
    }

    private void OnDisable()
    {
        if (_cancel != null)
        {
            _cancel.Cancel();
            _cancel.Dispose();
            _cancel = null;
        }
        Connected = false;
    }

    private void OnDestroy()
    {
        foreach (var go in _objects.Values)
        {
            if (go != null) Destroy(go);
        }
        _objects.Clear();
    }

    // Background task: connect, read messages, keep only the newest snapshot; reconnect on error.
    private async Task ReceiveLoop(CancellationToken cancel)
    {
        double delay = 0.5;
        var buffer = new byte[64 * 1024];
        while (!cancel.IsCancellationRequested)
        {
            using (var socket = new ClientWebSocket())
            {
                try
                {
                    if (!string.IsNullOrEmpty(Token))
                        socket.Options.SetRequestHeader("Authorization", "Bearer " + Token);
                    socket.Options.KeepAliveInterval = TimeSpan.FromSeconds(10);
                    await socket.ConnectAsync(new Uri(Url), cancel);
                    Connected = true;
                    delay = 0.5;
                    Debug.Log("MoMLocalizerClient: connected to " + Url);
                    using (var message = new MemoryStream())
                    {
                        while (socket.State == WebSocketState.Open && !cancel.IsCancellationRequested)
                        {
                            var result = await socket.ReceiveAsync(new ArraySegment<byte>(buffer), cancel);
                            if (result.MessageType == WebSocketMessageType.Close)
                            {
                                if ((int?)socket.CloseStatus == 4401)
                                {
                                    Debug.LogError("MoMLocalizerClient: the daemon rejected the token");
                                    Connected = false;
                                    return;
                                }
                                break;
                            }
                            message.Write(buffer, 0, result.Count);
                            if (!result.EndOfMessage) continue;
                            var text = Encoding.UTF8.GetString(message.GetBuffer(), 0, (int)message.Length);
                            message.SetLength(0);
                            var snapshot = JsonUtility.FromJson<Snapshot>(text);
                            if (snapshot != null)
                            {
                                lock (_lock) { _latest = snapshot; }
                            }
                        }
                    }
                }
                catch (OperationCanceledException)
                {
                    return;
                }
                catch (Exception error)
                {
                    Debug.LogWarning("MoMLocalizerClient: " + error.Message);
                }
            }
            Connected = false;
            try
            {
                await Task.Delay(TimeSpan.FromSeconds(delay), cancel);
            }
            catch (OperationCanceledException)
            {
                return;
            }
            delay = Math.Min(delay * 2, MaxBackoffSeconds);
        }
    }

    // Main thread: apply the newest snapshot, smooth motion, despawn people who left.
    private void Update()
    {
        Snapshot snapshot;
        lock (_lock)
        {
            snapshot = _latest;
            _latest = null;
        }
        float now = Time.time;
        if (snapshot != null && snapshot.people != null)
        {
            LastSeq = snapshot.seq;
            foreach (var person in snapshot.people)
            {
                if (person.confidence < MinConfidence) continue;
                var target = Origin + Scale * new Vector3(person.x, 0f, person.y);
                if (!_objects.TryGetValue(person.id, out var go) || go == null)
                {
                    go = PersonPrefab != null
                        ? Instantiate(PersonPrefab, target, Quaternion.identity, transform)
                        : CreateDefault(target);
                    go.name = "person " + person.id;
                    _objects[person.id] = go;
                }
                _targets[person.id] = target;
                _lastSeen[person.id] = now;
                var velocity = new Vector3(person.vx, 0f, person.vy);
                if (velocity.sqrMagnitude > 0.01f)
                    go.transform.rotation = Quaternion.LookRotation(velocity.normalized, Vector3.up);
            }
        }

        var gone = new List<int>();
        foreach (var entry in _objects)
        {
            if (entry.Value == null || now - _lastSeen[entry.Key] > DespawnSeconds)
            {
                gone.Add(entry.Key);
                continue;
            }
            var t = entry.Value.transform;
            var target = _targets[entry.Key];
            t.position = Smoothing <= 0f
                ? target
                : Vector3.Lerp(t.position, target, 1f - Mathf.Exp(-Smoothing * Time.deltaTime));
        }
        foreach (var id in gone)
        {
            if (_objects[id] != null) Destroy(_objects[id]);
            _objects.Remove(id);
            _targets.Remove(id);
            _lastSeen.Remove(id);
        }
    }

    private GameObject CreateDefault(Vector3 position)
    {
        // An empty root on the floor point with a 1.7 m capsule standing on it (Unity's capsule is
        // 2 units tall with its pivot in the middle, hence the 0.85 lift and scale).
        var root = new GameObject();
        root.transform.SetParent(transform, false);
        root.transform.position = position;
        var body = GameObject.CreatePrimitive(PrimitiveType.Capsule);
        body.transform.SetParent(root.transform, false);
        body.transform.localPosition = new Vector3(0f, 0.85f, 0f);
        body.transform.localScale = new Vector3(0.5f, 0.85f, 0.5f);
        return root;
    }
}
