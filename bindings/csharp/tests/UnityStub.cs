// The few UnityEngine types the Unity sample (unity/Samples~/AnimatorPartner/TroupePartner.cs)
// uses, with the behaviour the sample relies on and nothing more, so that the sample compiles and
// runs under Mono without the editor (tests/csharp.rs). Not Unity: a test double.
using System;

namespace UnityEngine
{
    public class Object { }

    public class Component : Object
    {
        public Transform transform = new Transform();
    }

    public class MonoBehaviour : Component { }

    /// <summary>A transform in a hierarchy, as Unity composes it (no scale): the world rotation
    /// is the parent's times the local one, the world position the parent's plus the parent's
    /// rotation of the local position.</summary>
    public sealed class Transform
    {
        public string name = "";
        public Vector3 localPosition;
        public Quaternion localRotation = Quaternion.identity;
        public Vector3 localScale = Vector3.one;
        private Transform parentTransform;
        private readonly System.Collections.Generic.List<Transform> children = new System.Collections.Generic.List<Transform>();

        public Transform() { }
        public Transform(string name, Transform parent, Vector3 localPosition)
        {
            this.name = name;
            this.localPosition = localPosition;
            this.parent = parent;
        }

        public Transform parent
        {
            get { return parentTransform; }
            set
            {
                if (parentTransform != null) parentTransform.children.Remove(this);
                parentTransform = value;
                if (value != null) value.children.Add(this);
            }
        }
        public int childCount { get { return children.Count; } }
        public Transform GetChild(int index) { return children[index]; }
        public Quaternion rotation
        {
            get { return parentTransform == null ? localRotation : parentTransform.rotation * localRotation; }
            set { localRotation = parentTransform == null ? value : Quaternion.Inverse(parentTransform.rotation) * value; }
        }
        public Vector3 position
        {
            get { return parentTransform == null ? localPosition : parentTransform.position + parentTransform.rotation * localPosition; }
            set
            {
                localPosition = parentTransform == null
                    ? value
                    : Quaternion.Inverse(parentTransform.rotation) * (value - parentTransform.position);
            }
        }
    }

    public struct Vector3
    {
        public float x, y, z;
        public Vector3(float x, float y, float z) { this.x = x; this.y = y; this.z = z; }
        public static Vector3 one { get { return new Vector3(1f, 1f, 1f); } }
        public static Vector3 operator *(Vector3 v, float s) { return new Vector3(v.x * s, v.y * s, v.z * s); }
        public static Vector3 operator +(Vector3 a, Vector3 b) { return new Vector3(a.x + b.x, a.y + b.y, a.z + b.z); }
        public static Vector3 operator -(Vector3 a, Vector3 b) { return new Vector3(a.x - b.x, a.y - b.y, a.z - b.z); }
        public float magnitude { get { return (float)Math.Sqrt(x * x + y * y + z * z); } }
        public static float Dot(Vector3 a, Vector3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
    }

    /// <summary>Unity's quaternion: (x, y, z, w), composed and applied to vectors as Unity does.</summary>
    public struct Quaternion
    {
        public float x, y, z, w;
        public Quaternion(float x, float y, float z, float w) { this.x = x; this.y = y; this.z = z; this.w = w; }
        public static Quaternion identity { get { return new Quaternion(0f, 0f, 0f, 1f); } }
        public static Quaternion Inverse(Quaternion q) { return new Quaternion(-q.x, -q.y, -q.z, q.w); }
        public static Quaternion operator *(Quaternion a, Quaternion b)
        {
            return new Quaternion(
                a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
                a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
                a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
                a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z);
        }
        public static Vector3 operator *(Quaternion q, Vector3 v)
        {
            // v + 2w (u x v) + 2 u x (u x v), u the vector part.
            float tx = 2f * (q.y * v.z - q.z * v.y), ty = 2f * (q.z * v.x - q.x * v.z), tz = 2f * (q.x * v.y - q.y * v.x);
            return new Vector3(v.x + q.w * tx + (q.y * tz - q.z * ty),
                               v.y + q.w * ty + (q.z * tx - q.x * tz),
                               v.z + q.w * tz + (q.x * ty - q.y * tx));
        }
    }

    /// <summary>An imported `.bytes` file.</summary>
    public class TextAsset : Object
    {
        public TextAsset(byte[] bytes) { this.bytes = bytes; }
        public byte[] bytes { get; private set; }
    }

    public static class Debug
    {
        public static void LogError(object message) { Console.Error.WriteLine(message); }
    }

    public enum PrimitiveType { Sphere }

    public sealed class GameObject : Object
    {
        public Transform transform = new Transform();
        public string name;
        public static GameObject CreatePrimitive(PrimitiveType type) { return new GameObject(); }
    }

    /// <summary>The engine's clock: the test sets the frame's duration before each Update.</summary>
    public static class Time
    {
        public static float deltaTime;
    }

    public static class Application
    {
        public static string streamingAssetsPath;
    }

    /// <summary>What a coroutine yields while a request runs (the stub's requests finish at once).</summary>
    public class AsyncOperation : Object { }

    [AttributeUsage(AttributeTargets.Field)]
    public sealed class TooltipAttribute : Attribute
    {
        public TooltipAttribute(string tooltip) { }
    }

    public enum HumanBodyBones
    {
        Hips, LeftUpperLeg, RightUpperLeg, LeftLowerLeg, RightLowerLeg, LeftFoot, RightFoot, Spine, Chest,
        Neck, Head, LeftShoulder, RightShoulder, LeftUpperArm, RightUpperArm, LeftLowerArm, RightLowerArm,
        LeftHand, RightHand, LeftToes, RightToes, UpperChest,
    }

    /// <summary>An Animator whose Humanoid bones the test gives (null where the rig lacks one).</summary>
    public sealed class Animator : Component
    {
        public Func<HumanBodyBones, Transform> bones;
        public Transform GetBoneTransform(HumanBodyBones bone) { return bones(bone); }
    }
}

namespace UnityEngine.Networking
{
    /// <summary>What the sample's Android path uses of UnityWebRequest: a GET whose download the
    /// coroutine waits for. The stub reads the URL's file (file:// or jar:file://...!/, whose
    /// part after the '!' the test maps to its folder).</summary>
    public sealed class UnityWebRequest : IDisposable
    {
        public enum Result { InProgress, Success, ConnectionError, ProtocolError, DataProcessingError }

        public sealed class DownloadHandler
        {
            public byte[] data { get; internal set; }
        }

        /// <summary>Where the test's APK is unpacked: a jar: URL's path after "!/" lies here.</summary>
        public static string apkRoot;

        private readonly string url;
        public Result result { get; private set; }
        public string error { get; private set; }
        public DownloadHandler downloadHandler { get; private set; }
        public static int requests;

        private UnityWebRequest(string url)
        {
            this.url = url;
            downloadHandler = new DownloadHandler();
        }

        public static UnityWebRequest Get(string uri) { return new UnityWebRequest(uri); }

        public AsyncOperation SendWebRequest()
        {
            requests++;
            int bang = url.IndexOf("!/", StringComparison.Ordinal);
            string path = url.StartsWith("jar:file://", StringComparison.Ordinal) && bang > 0
                ? System.IO.Path.Combine(apkRoot, url.Substring(bang + 2))
                : url;
            try
            {
                downloadHandler.data = System.IO.File.ReadAllBytes(path);
                result = Result.Success;
            }
            catch (System.IO.IOException e)
            {
                result = Result.ConnectionError;
                error = e.Message;
            }
            return new AsyncOperation();
        }

        public void Dispose() { }
    }
}
