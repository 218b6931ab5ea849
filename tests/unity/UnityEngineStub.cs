// A minimal stand-in for the few UnityEngine types examples/unity/MoMLocalizerClient.cs uses, so
// the client compiles and runs under Mono outside Unity (test only; never shipped).
//
// It mirrors the Unity behaviour the client relies on, not Unity's whole API:
// - a destroyed Object compares equal to null (Unity's overloaded ==);
// - OnEnable/OnDisable/Update are private methods the engine finds by name (here by reflection);
//   an inactive GameObject's components get OnEnable only when it is activated, which is how a
//   scene sets inspector fields before the component starts;
// - Transform is translation-only (parents are never rotated or scaled in the client's use);
// - Debug output goes to a sink the harness prints, one line per call.
using System;
using System.Collections.Generic;
using System.Reflection;

namespace UnityEngine
{
    public enum PrimitiveType { Sphere, Capsule, Cylinder, Cube, Plane, Quad }

    [AttributeUsage(AttributeTargets.Field)]
    public class TooltipAttribute : Attribute
    {
        public TooltipAttribute(string tooltip) { }
    }

    public struct Vector3
    {
        public float x, y, z;
        public Vector3(float x, float y, float z) { this.x = x; this.y = y; this.z = z; }
        public static Vector3 zero { get { return new Vector3(0, 0, 0); } }
        public static Vector3 up { get { return new Vector3(0, 1, 0); } }
        public float sqrMagnitude { get { return x * x + y * y + z * z; } }
        public Vector3 normalized
        {
            get
            {
                float m = (float)Math.Sqrt(sqrMagnitude);
                return m > 1e-5f ? new Vector3(x / m, y / m, z / m) : zero;
            }
        }
        public static Vector3 operator +(Vector3 a, Vector3 b) { return new Vector3(a.x + b.x, a.y + b.y, a.z + b.z); }
        public static Vector3 operator -(Vector3 a, Vector3 b) { return new Vector3(a.x - b.x, a.y - b.y, a.z - b.z); }
        public static Vector3 operator *(float s, Vector3 a) { return new Vector3(s * a.x, s * a.y, s * a.z); }
        public static Vector3 operator *(Vector3 a, float s) { return s * a; }
        public static Vector3 Lerp(Vector3 a, Vector3 b, float t)
        {
            t = Math.Max(0f, Math.Min(1f, t));
            return a + t * (b - a);
        }
        public override string ToString() { return "(" + x + ", " + y + ", " + z + ")"; }
    }

    public struct Quaternion
    {
        public Vector3 forward;  // stand-in: the direction LookRotation was given
        public static Quaternion identity { get { return new Quaternion { forward = new Vector3(0, 0, 1) }; } }
        public static Quaternion LookRotation(Vector3 forward, Vector3 upwards)
        {
            return new Quaternion { forward = forward };
        }
    }

    public static class Mathf
    {
        public static float Exp(float p) { return (float)Math.Exp(p); }
    }

    public static class Time
    {
        public static float time { get; private set; }
        public static float deltaTime { get; private set; }
        internal static void Advance(float dt) { deltaTime = dt; time += dt; }
    }

    public static class Debug
    {
        public static Action<string, string> Sink = (level, text) => Console.WriteLine(level + " " + text);
        public static void Log(object message) { Sink("LOG", message.ToString()); }
        public static void LogWarning(object message) { Sink("WARN", message.ToString()); }
        public static void LogError(object message) { Sink("ERROR", message.ToString()); }
    }

    public class Object
    {
        internal bool destroyed;
        public string name { get; set; }

        public static bool operator ==(Object a, Object b)
        {
            bool aNull = ReferenceEquals(a, null) || a.destroyed;
            bool bNull = ReferenceEquals(b, null) || b.destroyed;
            if (aNull || bNull) return aNull && bNull;
            return ReferenceEquals(a, b);
        }
        public static bool operator !=(Object a, Object b) { return !(a == b); }
        public override bool Equals(object other) { return this == (other as Object); }
        public override int GetHashCode() { return base.GetHashCode(); }

        public static void Destroy(Object target)
        {
            if (ReferenceEquals(target, null) || target.destroyed) return;
            var go = target as GameObject;
            if (go != null) go.DestroyTree();
            else target.destroyed = true;
        }

        public static T Instantiate<T>(T original, Vector3 position, Quaternion rotation, Transform parent) where T : Object
        {
            var source = original as GameObject;
            if (source == null) throw new NotSupportedException("stub: only GameObjects can be instantiated");
            var copy = new GameObject(source.name + "(Clone)");
            copy.transform.SetParent(parent, false);
            copy.transform.position = position;
            copy.transform.rotation = rotation;
            return (T)(Object)copy;
        }
    }

    public class Component : Object
    {
        public GameObject gameObject { get; internal set; }
        public Transform transform { get { return gameObject.transform; } }
    }

    public class Behaviour : Component
    {
        public bool enabled = true;
    }

    public class MonoBehaviour : Behaviour
    {
        internal void Call(string method)
        {
            var m = GetType().GetMethod(method, BindingFlags.Instance | BindingFlags.Public | BindingFlags.NonPublic);
            if (m != null) m.Invoke(this, null);
        }
    }

    public class Transform : Component
    {
        private readonly List<Transform> _children = new List<Transform>();
        public Transform parent { get; private set; }
        public Vector3 localPosition = Vector3.zero;
        public Vector3 localScale = new Vector3(1, 1, 1);
        public Quaternion rotation = Quaternion.identity;
        public int childCount { get { return _children.Count; } }
        public Transform GetChild(int i) { return _children[i]; }
        internal List<Transform> Children { get { return _children; } }

        public Vector3 position
        {
            get { return parent == null ? localPosition : parent.position + localPosition; }
            set { localPosition = parent == null ? value : value - parent.position; }
        }

        public void SetParent(Transform newParent, bool worldPositionStays)
        {
            var world = position;
            if (parent != null) parent._children.Remove(this);
            parent = newParent;
            if (parent != null) parent._children.Add(this);
            if (worldPositionStays) position = world;
        }
    }

    public class GameObject : Object
    {
        internal static readonly List<GameObject> Live = new List<GameObject>();
        private readonly List<Component> _components = new List<Component>();
        public Transform transform { get; private set; }
        public bool activeSelf { get; private set; }

        public GameObject() : this("New Game Object") { }

        public GameObject(string name)
        {
            this.name = name;
            activeSelf = true;
            transform = new Transform { gameObject = this };
            Live.Add(this);
        }

        public T AddComponent<T>() where T : Component, new()
        {
            var component = new T { gameObject = this };
            _components.Add(component);
            var behaviour = component as MonoBehaviour;
            if (behaviour != null)
            {
                behaviour.Call("Awake");
                if (activeSelf && behaviour.enabled) behaviour.Call("OnEnable");
            }
            return component;
        }

        public void SetActive(bool value)
        {
            if (value == activeSelf) return;
            activeSelf = value;
            foreach (var b in Behaviours()) b.Call(value ? "OnEnable" : "OnDisable");
        }

        public static GameObject CreatePrimitive(PrimitiveType type)
        {
            return new GameObject(type.ToString());
        }

        internal IEnumerable<MonoBehaviour> Behaviours()
        {
            foreach (var c in _components)
            {
                var b = c as MonoBehaviour;
                if (b != null && b.enabled) yield return b;
            }
        }

        internal void DestroyTree()
        {
            foreach (var child in transform.Children.ToArray()) child.gameObject.DestroyTree();
            if (activeSelf) foreach (var b in Behaviours()) b.Call("OnDisable");
            foreach (var b in Behaviours()) b.Call("OnDestroy");
            transform.SetParent(null, false);
            destroyed = true;
            Live.Remove(this);
        }
    }

    /// <summary>The engine's frame loop, driven by the test harness.</summary>
    public static class StubPlayerLoop
    {
        public static IList<GameObject> LiveObjects { get { return GameObject.Live.AsReadOnly(); } }

        public static void Tick(float deltaTime)
        {
            Time.Advance(deltaTime);
            foreach (var go in GameObject.Live.ToArray())
            {
                if (!go.activeSelf || go.destroyed) continue;
                foreach (var b in new List<MonoBehaviour>(go.Behaviours())) b.Call("Update");
            }
        }
    }
}
