// How the marshaller lays out the binding's structs, for tests/binding_coverage.rs to compare
// with the C compiler's layout of include/troupe.h. Compiled with Troupe.cs into one program:
//
//   mono layouts.exe NAME...
//
// prints, for each struct NAME, `S NAME <size>` and one `F NAME <field> <offset> <size>` per leaf
// field (a nested struct's fields flattened, an array one field), in bytes; then `P NAME` for
// every struct type a P/Invoke declaration passes or returns (by value, by reference or as an
// array), so the test can insist that each of those is one it compares.
using System;
using System.Linq;
using System.Reflection;
using System.Runtime.InteropServices;

static class Layouts
{
    const BindingFlags Fields = BindingFlags.Instance | BindingFlags.Public | BindingFlags.NonPublic;
    const BindingFlags Methods = BindingFlags.Static | BindingFlags.Public | BindingFlags.NonPublic;

    // A struct whose fields the marshaller lays out itself (not a number, pointer or enum).
    static bool IsComposite(Type t)
    {
        return t.IsValueType && !t.IsPrimitive && !t.IsEnum && t != typeof(void);
    }

    static int LeafSize(FieldInfo field)
    {
        Type t = field.FieldType;
        if (t.IsArray)
        {
            var marshalAs = (MarshalAsAttribute)field
                .GetCustomAttributes(typeof(MarshalAsAttribute), false)
                .FirstOrDefault();
            if (marshalAs == null || marshalAs.Value != UnmanagedType.ByValArray)
            {
                throw new Exception(field.DeclaringType.Name + "." + field.Name +
                    " is an array without [MarshalAs(UnmanagedType.ByValArray)]");
            }
            return marshalAs.SizeConst * Marshal.SizeOf(t.GetElementType());
        }
        return Marshal.SizeOf(t.IsEnum ? Enum.GetUnderlyingType(t) : t);
    }

    static void PrintLeaves(string name, Type t, long start)
    {
        var fields = t.GetFields(Fields)
            .Select(f => new { Field = f, Offset = start + Marshal.OffsetOf(t, f.Name).ToInt64() })
            .OrderBy(f => f.Offset);
        foreach (var f in fields)
        {
            if (IsComposite(f.Field.FieldType))
            {
                PrintLeaves(name, f.Field.FieldType, f.Offset);
            }
            else
            {
                Console.WriteLine("F {0} {1} {2} {3}", name, f.Field.Name, f.Offset, LeafSize(f.Field));
            }
        }
    }

    static int Main(string[] names)
    {
        Type[] types = typeof(Troupe.Library).Assembly.GetTypes();
        foreach (string name in names)
        {
            Type t = types.Single(candidate => candidate.Name == name);
            Console.WriteLine("S {0} {1}", name, Marshal.SizeOf(t));
            PrintLeaves(name, t, 0);
        }
        var passed = types
            .SelectMany(t => t.GetMethods(Methods))
            .Where(m => m.GetCustomAttributes(typeof(DllImportAttribute), false).Length > 0)
            .SelectMany(m => m.GetParameters().Select(p => p.ParameterType).Concat(new[] { m.ReturnType }))
            .Select(t => t.IsByRef || t.IsArray || t.IsPointer ? t.GetElementType() : t)
            .Where(IsComposite)
            .Select(t => t.Name)
            .Distinct()
            .OrderBy(n => n);
        foreach (string name in passed)
        {
            Console.WriteLine("P {0}", name);
        }
        return 0;
    }
}
