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

    public sealed class Transform
    {
        public Vector3 position;
        public Vector3 localScale = Vector3.one;
    }

    public struct Vector3
    {
        public float x, y, z;
        public Vector3(float x, float y, float z) { this.x = x; this.y = y; this.z = z; }
        public static Vector3 one { get { return new Vector3(1f, 1f, 1f); } }
        public static Vector3 operator *(Vector3 v, float s) { return new Vector3(v.x * s, v.y * s, v.z * s); }
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

    /// <summary>A Humanoid Animator whose bones the test moves.</summary>
    public sealed class Animator : Component
    {
        public Func<HumanBodyBones, Transform> bones;
        public Transform GetBoneTransform(HumanBodyBones bone) { return bones(bone); }
    }
}
